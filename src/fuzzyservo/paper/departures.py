"""Where fuzzyservo departs from, or has to complete, the paper, and why.

The report prints this list; docs/model.md explains each item at length, and a test checks that
every topic here appears there.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["DEPARTURES", "Departure"]


@dataclass(frozen=True, slots=True)
class Departure:
    """One departure: what the paper says, what fuzzyservo does, and the reason."""

    topic: str
    paper: str
    ours: str
    reason: str


DEPARTURES: tuple[Departure, ...] = (
    Departure(
        "Supply pressure",
        "70 MPa +- 500 kPa (Table A.1)",
        "7 MPa (70 bar); the +-500 kPa is available as supply ripple",
        "70 MPa is far above servovalve ratings and equals Moog's 70 bar rating drop; with "
        "7 MPa the rated flow, K_c and the cylinder size are mutually consistent.",
    ),
    Departure(
        "Valve flow gain",
        "2.613e-3 m^3/s/mA, no load (Table A.1)",
        "2.613e-3 m^3/s is the no-load extension flow at rated command (157 L/min)",
        "Read per mA it gives 1570 L/min at 10 mA, read per A 1.6 L/min; neither fits a "
        "113 mm cylinder on a manipulator.",
    ),
    Departure(
        "Loop gain K_o",
        "K_o = K_tr C_v A_f / K_v (eq. 8)",
        "K_o = K_a K_tr C_v / A_f = Q_rated / A_f per unit command (position in metres)",
        "The printed formula is dimensionally wrong; eq. (7) puts A_f in the denominator.",
    ),
    Departure(
        "Missing plant data",
        "M, V_f, V_n, bulk modulus, tau_v, C_d, W, rho, K_tr, sample time not given",
        "Derived in code so that the linearisation gives omega_0 = 19.6 rad/s and "
        "delta = 0.1 at mid-stroke while every Table A.1 value is kept (set 'paper')",
        "Table A.1 is inconsistent with stiff oil and cylinder volumes alone (model notes "
        "section 4); a hose-compliant set reproduces its numbers and its 6 ms hose delay.",
    ),
    Departure(
        "Eq. (4) compressibility term",
        "P_le without time derivative",
        "dP/dt in the chamber continuity equations",
        "Compressibility flow is proportional to the rate of change of pressure.",
    ),
    Departure(
        "Controller signal units",
        "PID and fuzzy gains given without units; error in volts (eq. 8)",
        "Controllers read position in metres and command the valve as a fraction of rated "
        "input; the paper's PID gains are used as 1/m, 1/(m s), s/m",
        "The transducer and amplifier gains are not given; this reading makes K_tr K_a = 1 "
        "per metre and is stated with every result.",
    ),
    Departure(
        "PID structure",
        "PID tuned in MATLAB, structure and derivative filter not stated",
        "Parallel PID with derivative filter N = 100 (Simulink default); a 2-DOF PID "
        "(setpoint weight b, derivative on measurement) is tuned as a fairer baseline",
        "On an integrating plant a 1-DOF PID must overshoot (integral of e is zero), so the "
        "paper's zero-overshoot PID needs another structure (model notes section 5).",
    ),
    Departure(
        "Self-tuning step 3",
        "Fine-tune the alpha rules for the desired response",
        "The published alpha rules are kept; the three gains are refined instead",
        "Changing the rules would no longer test the paper's controller.",
    ),
    Departure(
        "Initial conditions of the fuzzy PI",
        "Not stated",
        "u(-1) = 0 (trim command on the nonlinear plant) and e(-1) = 0; delta-e per sample",
        "Mudi and Pal's incremental form; both are parameters of the controller.",
    ),
)
