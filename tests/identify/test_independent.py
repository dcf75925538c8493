"""Issue 27's independence check: data from a model this project did not write are fitted to
within the fit's stated intervals.

The data come from the textbook valve-controlled asymmetric cylinder (Merritt, Hydraulic
Control Systems, 1967, ch. 5-6; Jelali & Kroll, Hydraulic Servo-systems, 2003, ch. 3), written
out below and integrated with scipy's ``solve_ivp``; the project's ``rhs`` is not called.

- spool, second order: x_v'' = w_v^2 (u(t - tau) - x_v) - 2 z_v w_v x_v'  (x_v per rated opening)
- turbulent orifices of a critically lapped 4/3 valve, sgn(dp) sqrt|dp|:
  x_v >= 0: Q_A = K_v x_v sqrt(p_S - p_A), Q_B = K_v x_v sqrt(p_B - p_T);
  x_v < 0:  Q_A = K_v x_v sqrt(p_A - p_T), Q_B = K_v x_v sqrt(p_S - p_B)
- chambers: p_A' = beta/(V_A0 + A_A x) (Q_A - A_A v), p_B' = beta/(V_B0 + A_B (L - x)) (A_B v - Q_B)
- load: M v' = A_A p_A - A_B p_B - B v (no Coulomb friction, no leakage)

The project's parameter set that describes the same physics: the textbook's K_v is the
orifice coefficient G, so ``valve.rated_flow`` = K_v sqrt((p_S - p_T)/(1 + r^3)) (the no-load
extension flow, docs/model.md "Flow gain"); the chamber volumes are the dead volumes, with no
hose and a cylinder wall of 1e18 Pa (its compliance in series with the oil's is then 1e-9 of
it); no null or internal leakage, no Coulomb or static friction, B the viscous damping; the
laminar-transition pressure lowered from 1 bar to 1 kPa, where R(dp) = dp/(dp^2 + p_cr^2)^(1/4)
differs from sqrt(dp) by (p_cr/dp)^2/4 < 3e-5 at the smallest drop of this run (5 bar). At
rest the leak-free valve holds any pressures with A_A p_A = A_B p_B; both models take the
limit of equal laminar leakage on the four lands as it vanishes (below).

Measured (noise-free, at the true parameters): the project's model with RK4 substeps of
0.5 ms follows these data to 2e-4 of the 30 dB noise's standard deviation in position and
6e-4 in pressure (0.1 ms: 2e-5), so the default substep is the honest one. The command is
kept small (4 % of rated) so that no chamber pressure approaches the tank: at 15 % p_A fell
to -1 bar in the textbook model, below the project's cavitation floor (0 Pa with a 1 bar
band, docs/model.md), and the two models then differ by 0.1 sigma, which is the difference
of those models, not of the fit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest
from scipy import integrate, optimize

from fuzzyservo.identify import FitSettings, Identification, identify
from fuzzyservo.paper.published import named_set
from fuzzyservo.plant import ServoParams, with_overrides

# The textbook axis: the paper's cylinder and valve, other values chosen (SI units).
BORE, ROD, STROKE = 0.1127, 0.0704, 1.0  # [m]
A_A = math.pi / 4.0 * BORE**2  # [m²]
A_B = math.pi / 4.0 * (BORE**2 - ROD**2)  # [m²]
P_S, P_T = 7.0e6, 0.0  # [Pa]
K_V = 0.61 * 3.74e-5 * math.sqrt(2.0 / 870.0)  # C_d w x_v,max sqrt(2/rho) [m³/(s·Pa^0.5)]
V_A0 = V_B0 = 2.8e-3  # chamber and line volume at the end of each chamber's stroke [m³]
B_VISC = 7.0e4  # [N·s/m]
Z_V = 0.3572  # [1]
TAU = 0.006  # transport delay on the command [s]
X0 = 0.5  # start position [m]
DT = 1.0e-3  # [s]
DURATION = 10.0  # [s]
REST = 500  # samples at rest before the excitation
AMPLITUDE = 0.04  # command amplitude [1]

#: The truth: the fitted parameters of the textbook axis.
TRUTH = {"load.mass": 18583.4, "fluid.oil_bulk_modulus": 1.2e9, "valve.omega_v": 530.0}
FIT = tuple(TRUTH)


def _root(dp: float) -> float:
    return math.copysign(math.sqrt(abs(dp)), dp)


def textbook_rhs(t: float, s: np.ndarray, u: float, mass: float, beta: float,
                 omega_v: float) -> list[float]:
    """d/dt of (x_v, x_v', p_A, p_B, x, v) with the valve input ``u`` held."""
    xv, vv, pa, pb, x, v = s
    if xv >= 0.0:
        qa, qb = K_V * xv * _root(P_S - pa), K_V * xv * _root(pb - P_T)
    else:
        qa, qb = K_V * xv * _root(pa - P_T), K_V * xv * _root(P_S - pb)
    return [vv,
            omega_v * omega_v * (u - xv) - 2.0 * Z_V * omega_v * vv,
            beta / (V_A0 + A_A * x) * (qa - A_A * v),
            beta / (V_B0 + A_B * (STROKE - x)) * (A_B * v - qb),
            v,
            (A_A * pa - A_B * pb - B_VISC * v) / mass]


def rest_pressures() -> tuple[float, float]:
    """p_A, p_B at rest: A_A p_A = A_B p_B, and the centred valve's lands leak equally
    (K_l dp each) while a small opening x_v < 0 balances the leakage; as K_l -> 0 the ratio
    x_v/K_l stays finite and K_v |x_v|/K_l sqrt(p_A - p_T) = p_S + p_T - 2 p_A,
    K_v |x_v|/K_l sqrt(p_S - p_B) = 2 p_B - p_S - p_T, whose ratio fixes p_A [Pa]."""
    r = A_B / A_A

    def g(pa: float) -> float:
        pb = pa / r
        return (math.sqrt(pa - P_T) * (2.0 * pb - P_S - P_T)
                - math.sqrt(P_S - pb) * (P_S + P_T - 2.0 * pa))

    pa = optimize.brentq(g, P_T + 1.0, r * P_S - 1.0, xtol=1e-6, rtol=1e-14)
    return pa, pa / r


def command() -> tuple[np.ndarray, np.ndarray]:
    """Sample times and the command: rest, pulses of both signs, a log chirp 1 -> 80 Hz."""
    n = int(round(DURATION / DT)) + 1
    t = np.arange(n) * DT
    u = np.zeros(n)

    def during(t0: float, t1: float) -> np.ndarray:
        return (t >= t0 - 1e-9) & (t < t1 - 1e-9)

    u[during(0.5, 1.0)] = AMPLITUDE
    u[during(1.0, 1.5)] = -AMPLITUDE
    u[during(2.0, 2.5)] = -AMPLITUDE
    u[during(2.5, 3.0)] = AMPLITUDE
    chirp = during(4.0, 9.5)
    k = 80.0 ** (1.0 / 5.5)
    u[chirp] = AMPLITUDE * np.sin(2.0 * np.pi * (k ** (t[chirp] - 4.0) - 1.0) / math.log(k))
    return t, u


def textbook_run(u: np.ndarray) -> np.ndarray:
    """States (n, 6) at the sample times: the command held over each sample, delayed by
    TAU (a whole number of samples), integrated segment by segment between the instants
    where the valve's input changes (DOP853, rtol 1e-10: the equations are not stiff at
    this operating point, valve poles -190 ± 500j 1/s; an explicit 8th-order method is
    the accurate and quick choice)."""
    n = u.size
    d = int(round(TAU / DT))
    valve_in = np.concatenate([np.zeros(d), u])[:n]  # held on [t_k, t_k+1)
    pa, pb = rest_pressures()
    s = np.array([0.0, 0.0, pa, pb, X0, 0.0])
    atol = 1e-10 * np.array([1.0, 500.0, P_S, P_S, 1.0, 1.0])
    args = (TRUTH["load.mass"], TRUTH["fluid.oil_bulk_modulus"], TRUTH["valve.omega_v"])
    out = np.empty((n, 6))
    out[0] = s
    k = 0
    while k < n - 1:
        j = k + 1
        while j < n - 1 and valve_in[j] == valve_in[k]:
            j += 1
        tt = np.arange(k, j + 1) * DT
        sol = integrate.solve_ivp(textbook_rhs, (tt[0], tt[-1]), s, method="DOP853",
                                  t_eval=tt, args=(float(valve_in[k]), *args), rtol=1e-10,
                                  atol=atol)
        assert sol.success, sol.message
        out[k + 1:j + 1] = sol.y[:, 1:].T
        s = sol.y[:, -1].copy()
        k = j
    return out


@dataclass(frozen=True, slots=True, kw_only=True)
class Log:
    """A logged open-loop experiment, as :func:`fuzzyservo.identify.identify` reads it."""

    t: np.ndarray
    dt: float
    y: np.ndarray
    u: np.ndarray
    p_f: np.ndarray
    p_n: np.ndarray
    r: None = None
    flagged: None = None
    rest: int = REST


def project_set() -> ServoParams:
    """The project's parameter set describing the textbook axis, with the paper set's mass,
    oil modulus and spool frequency as the fit's starting values (-20 %, +25 %, +30 %)."""
    r3 = (A_B / A_A) ** 3
    return with_overrides(named_set("paper"), {
        "cylinder.bore": BORE, "cylinder.rod_diameter": ROD, "cylinder.stroke": STROKE,
        "cylinder.dead_volume_f": V_A0, "cylinder.dead_volume_n": V_B0,
        "cylinder.internal_leakage": 0.0,
        "fluid.hose_volume": 0.0, "fluid.cylinder_wall_bulk_modulus": 1e18,
        "valve.null_leakage": 0.0, "valve.laminar_pressure": 1e3, "valve.zeta_v": Z_V,
        "valve.tau_v": 0.0, "valve.rated_flow": K_V * math.sqrt((P_S - P_T) / (1.0 + r3)),
        "load.coulomb_friction": 0.0, "load.static_friction": 0.0,
        "load.viscous_damping": B_VISC, "load.external_force": 0.0,
        "supply.pressure": P_S, "supply.tank_pressure": P_T, "supply.ripple_amplitude": 0.0,
        "delay.transport_delay": TAU,
    })


@pytest.fixture(scope="module")
def clean() -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """The textbook axis's run: sample times, command, and the logged channels noise-free."""
    t, u = command()
    x = textbook_run(u)
    assert 5e5 < min(x[:, 2].min(), x[:, 3].min())  # far from the cavitation floor
    assert max(x[:, 2].max(), x[:, 3].max()) < P_S - 5e5
    return t, u, {"y": x[:, 4], "p_f": x[:, 2], "p_n": x[:, 3]}


def noisy(clean: tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]],
          seed: int) -> tuple[Log, dict[str, float]]:
    """The run with 30 dB of white noise on each channel (standard deviation of the signal
    over sqrt(1000)), seeded; and each channel's noise level. The logged command carries a
    null offset of 1 % (the fit replaces its rest value with the model's holding command)."""
    t, u, x = clean
    rng = np.random.default_rng(seed)
    sd = {c: float(np.std(v)) / math.sqrt(1000.0) for c, v in x.items()}
    y = {c: v + rng.normal(0.0, sd[c], v.size) for c, v in x.items()}
    return Log(t=t, dt=DT, y=y["y"], u=u + 0.01, p_f=y["p_f"], p_n=y["p_n"]), sd


def fit(log: Log) -> Identification:
    return identify(log, plant="nonlinear", params=project_set(), fit=FIT, substep=5e-4,
                    settings=FitSettings(starts=1, seed=0, bootstrap=12))


def inside(res: Identification) -> tuple[np.ndarray, np.ndarray]:
    """Whether the truth lies inside estimate ± 1.96 SE, and inside the bootstrap's
    percentile interval, per parameter."""
    truth = np.array([TRUTH[n] for n in res.names])
    se = (np.abs(res.estimate - truth) <= 1.96 * res.std_error)
    assert res.interval is not None
    boot = (res.interval[:, 0] <= truth) & (truth <= res.interval[:, 1])
    return se, boot


def test_textbook_data_fitted_within_stated_intervals(
        clean: tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]) -> None:
    """The seed was fixed before the first run. Over seeds 0-9 of the same experiment the
    truth fell outside estimate ± 1.96 SE for some parameter in 1 of 10 (three parameters,
    mass and bulk modulus correlated: about 1 in 10 expected) and outside the 12-refit
    bootstrap interval in 2 of 10 (percentiles of 12 refits are nearly their extremes)."""
    log, sd = noisy(clean, 2027)
    res = fit(log)
    truth = np.array([TRUTH[n] for n in res.names])
    assert np.all(np.abs(res.initial / truth - 1.0) > 0.19)  # the fit starts 20-30 % off
    # the model describes the data to their noise: residuals at the added noise level
    for c in ("y", "p_f", "p_n"):
        assert res.residual_rms[c] == pytest.approx(sd[c], rel=0.03), c
    assert np.all(np.abs(res.estimate / truth - 1.0) < 0.02)
    se, boot = inside(res)
    assert np.all(se), (res.estimate - truth) / res.std_error
    assert np.all(boot), (res.interval, truth)
    assert res.warnings == ()


def test_the_start_positions_error_does_not_bias_the_fit(
        clean: tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]) -> None:
    """Seed 7 put omega_v 3.8 SE off, its bootstrap interval beside the estimate, while the
    start position was the mean of the noisy rest samples and the position compared as it
    was: that error, sigma_y/sqrt(500), is a constant offset of the whole position trace. The
    fit now compares the position up to a constant fitted with the parameters."""
    res = fit(noisy(clean, 7)[0])
    se, boot = inside(res)
    assert np.all(se) and np.all(boot)
    assert any("compared up to a constant" in n for n in res.notes)
