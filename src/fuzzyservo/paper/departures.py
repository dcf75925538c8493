"""Where fuzzyservo departs from, or has to complete, the paper, and why; and likewise for the
published schemes it implements beside the paper's controllers.

The report prints :data:`DEPARTURES`; docs/model.md explains each item at length, and a test
checks that every topic here (those of :data:`WOO_DEPARTURES` too) appears there.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["DEPARTURES", "WOO_2000", "WOO_DEPARTURES", "Departure"]


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

#: The source of the ``wfpi`` kind (``fuzzyservo.control.woo``).
WOO_2000 = ("Z.-W. Woo, H.-Y. Chung, J.-J. Lin, A PID type fuzzy controller with self-tuning "
            "scaling factors, Fuzzy Sets and Systems 115(2), 321-326, 2000")

#: Where the ``wfpi`` kind departs from Woo, Chung & Lin (2000) (:data:`WOO_2000`), and why;
#: ``paper`` is what Woo et al. do. docs/model.md, "Baselines beside the paper's controllers".
WOO_DEPARTURES: tuple[Departure, ...] = (
    Departure(
        "Woo: source text not checked",
        "phi(e) = a|e| + b and psi(e) = c(1 - |e|) + d rescale the error-change input factor "
        "and the integral output factor on line",
        "These forms and roles, reconstructed from later accounts of the scheme; the "
        "paper's text, its rule base and its coefficient values were not available here",
        "No copy of the article was reachable from this workplace; every item below that "
        "names Woo et al.'s choices should be checked against it.",
    ),
    Departure(
        "Woo: controller type",
        "PID type: a fuzzy PD map whose output feeds a proportional path (factor alpha) and "
        "an integrating path (factor beta)",
        "PI type: the paper's incremental fuzzy PI, i.e. the integrating path alone (alpha = "
        "0), no derivative-like action",
        "The comparison is between self-tuning schemes on one base controller, the paper's "
        "stfpi's; a derivative path would change the controller as well as the tuning.",
    ),
    Departure(
        "Woo: rule base",
        "Their own fuzzy PD rule base and membership functions",
        "The paper's Fig. 3a delta-u rule base, triangles and exact centroid (the du system)",
        "The same base map as fpi and stfpi, so only the source of the scaling differs.",
    ),
    Departure(
        "Woo: what phi and psi scale",
        "phi the error-change input factor K_d, psi the integral output factor beta",
        "phi multiplies K_de (the error-change scaling), psi multiplies K_du (the output "
        "scaling; the run's alpha trace)",
        "In the incremental fuzzy PI, K_de and K_du hold the places of K_d and beta in the "
        "integrating path: proportional gain ~ psi phi K_du K_de, integral gain ~ psi K_du K_e.",
    ),
    Departure(
        "Woo: error normalisation",
        "|e| of the (unit-step) error, in [0, 1] for the step responses studied",
        "m = min(|K_e e|, 1), the normalised error the rule base sees, clipped",
        "The functions then see the error the fuzzy map sees; with K_e = 1/step, m = |e|/step.",
    ),
    Departure(
        "Woo: coefficients",
        "a, b, c, d chosen by the designer for each plant",
        "b = d = 1 held; a and c in [0, 9] tuned with K_e, K_de, K_du by the project's tuner "
        "(ITAE, the same constraints as the other kinds)",
        "A free b or d only rescales K_de or K_du; a and c are the scheme's shape and are "
        "tuned like every other kind's gains rather than guessed.",
    ),
)
