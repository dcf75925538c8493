"""The paper's claims, each tested on simulation results and given a verdict.

Every verdict and number here is computed from the records passed in: nothing is typed in.
A claim "holds" when the simulation supports it as the paper states it, "does not hold" when the
simulation contradicts it, and "holds under stated conditions" when it holds only in part
(the evidence names the part). Each :class:`Claim` carries its sentence of evidence, the rule
applied (:data:`CLAIM_RULES`, the same text as docs/model.md, "How a verdict is reached"), the
thresholds of that rule and the numbers it used, per controller or per changed plant.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .._typing import FloatArray
from ..analysis.outcome import (
    LIMIT_CYCLE_MIN_PP,
    LIMIT_CYCLE_MIN_SUSTAIN,
    LIMIT_CYCLE_MIN_SWINGS,
    MAX_OVERSHOOT_PCT,
    TAIL_FRACTION,
    classify,
    tail_oscillation,
)

__all__ = [
    "CLAIM_RULES",
    "CLAIM_SHORT",
    "CLAIM_TEXTS",
    "HOLDS",
    "KICK_TIME_CONSTANTS",
    "NOT_HOLDS",
    "NO_OVERSHOOT_PCT",
    "NO_SSE_FRACTION",
    "PARTLY",
    "Claim",
    "Outcome",
    "Trace",
    "Value",
    "alpha_settles",
    "command_amplitude",
    "evaluate_claims",
    "response_outcome",
    "summarize",
    "transient_window",
]

HOLDS = "holds"
NOT_HOLDS = "does not hold"
PARTLY = "holds under stated conditions"

#: "No overshoot" is read as an overshoot of at most this much [% of the step]: 0.5 % of a
#: 0.1 m step is 0.5 mm, below what the paper's plots could show.
NO_OVERSHOOT_PCT = 0.5
#: A steady-state error counts as "none" below this fraction of the step [-].
NO_SSE_FRACTION = 0.005
#: C3's "after the initial transient" starts this many derivative-filter time constants 1/N
#: after the step (N of the paper's PIDs, or the sample time for an unfiltered derivative):
#: the derivative kick kd N dr (7.5 for PID (1.2, 1, 0.75), N = 100 1/s, a 0.1 m step) falls
#: below the command limit 1 after ln(7.5)/N = 20 ms and to e^-10 (5e-5) of its start by
#: 10/N = 0.1 s, so nothing of it is left in the window [-].
KICK_TIME_CONSTANTS = 10.0
#: α_F is constant when its spread over the tail is at most this (1/100 of its range) [-].
ALPHA_MAX_SPREAD = 0.01

CLAIM_TEXTS: dict[str, str] = {
    "C1": "The self-tuning fuzzy PI has no overshoot.",
    "C2": "The self-tuning fuzzy PI rises and settles faster than the PIDs.",
    "C3": "The self-tuning fuzzy PI's control amplitude is smaller than both PIDs'.",
    "C4": "The self-tuning factor α_F settles to a constant.",
    "C5": "The fuzzy PI without self-tuning settles more slowly.",
    "C6": "The self-tuning fuzzy PI stays robust with the 6 ms hose delay.",
    "C7": "PID (1.2, 1, 0.75) gives at most 10 % overshoot and no steady-state error, "
          "and PID (0.8, 0.55, 0.5) no overshoot.",
    "C8": "The self-tuning fuzzy PI stays robust, and faster than PID, when a system parameter "
          "changes (gains fixed).",
    "C9": "The self-tuning fuzzy PI tracks a moving reference (the abstract: \"the tracking "
          "ability of the controller [was] demonstrated through simulations\").",
}

#: A few words per claim, for the summary and the verdict grid.
CLAIM_SHORT: dict[str, str] = {
    "C1": "no overshoot",
    "C2": "faster than the PIDs",
    "C3": "smaller control amplitude",
    "C4": "α_F settles",
    "C5": "fuzzy PI settles more slowly",
    "C6": "robust with the hose delay",
    "C7": "the paper's PIDs as it describes them",
    "C8": "robust to parameter changes",
    "C9": "tracking ability",
}

_ROBUST = (f"robust: it settles into the 2 % band within the run, overshoots at most "
           f"{MAX_OVERSHOOT_PCT:g} %, does not diverge and ends in no limit cycle (over the "
           f"last {TAIL_FRACTION * 100:g} % of the run: a peak-to-peak of at least "
           f"{LIMIT_CYCLE_MIN_PP * 100:g} % of the step, at least {LIMIT_CYCLE_MIN_SWINGS} "
           f"swings across its mean, and the second half's peak-to-peak at least "
           f"{LIMIT_CYCLE_MIN_SUSTAIN:g} of the first half's)")

#: C9: a sine counts when its peak speed A 2π f is within the valve's no-load speed at the
#: full command (beyond it every design saturates and none can follow); on each that counts
#: the first harmonic of y must be within these bounds of r's, and the RMS error within
#: TRACK_RMS_VS_BEST x the best design's of the study (baselines included) [-, -, deg, -].
TRACK_RATIO_MIN, TRACK_RATIO_MAX, TRACK_LAG_MAX_DEG, TRACK_RMS_VS_BEST = 0.9, 1.1, 30.0, 1.5

#: The rule of each verdict, as docs/model.md ("How a verdict is reached") states it.
CLAIM_RULES: dict[str, str] = {
    "C1": (f"holds when the overshoot is <= {NO_OVERSHOOT_PCT:g} % of the step; under stated "
           f"conditions when the no-overshoot design meets it only because it was tuned under "
           f"that very constraint while the design tuned like the PIDs overshoots"),
    "C2": ("holds when its rise and 2 % settling times are below every PID's (never settling "
           "is slowest); under stated conditions when it beats the paper's PIDs but not a "
           "tuned one; else does not hold"),
    "C3": (f"three measures of the command against both paper PIDs: the peak |u| over the "
           f"run, the peak |u| after the initial transient (from {KICK_TIME_CONSTANTS:g} "
           f"derivative-filter time constants 1/N after the step) and the RMS of u over the "
           f"run; holds when it is smaller by all three, under stated conditions when by "
           f"some (named), else does not hold"),
    "C4": (f"holds when α_F's spread over the last {TAIL_FRACTION * 100:g} % of the run "
           f"is <= {ALPHA_MAX_SPREAD:g}"),
    "C5": "holds when the fuzzy PI's 2 % settling time exceeds the self-tuning one's",
    "C6": (f"holds when the run with the hose delay is {_ROBUST}, and no controller of the "
           f"delay sweep settles up to a larger delay; under stated conditions when one does; "
           f"else does not hold"),
    "C7": (f"three parts: PID (1.2, 1, 0.75) overshoots at most {MAX_OVERSHOOT_PCT:g} %; it "
           f"settles within the run with a steady-state error of at most "
           f"{NO_SSE_FRACTION * 100:g} % of the step (an unsettled response has no "
           f"steady-state error to quote); PID (0.8, 0.55, 0.5) overshoots at most "
           f"{NO_OVERSHOOT_PCT:g} %; holds when all three do, under stated conditions when "
           f"some do (named), else does not hold"),
    "C8": (f"on every changed plant the self-tuning fuzzy PI must be {_ROBUST}; it does not "
           f"hold if any change fails; with every change robust it holds when it also settles "
           f"faster than both paper PIDs on each, else under stated conditions"),
    "C9": (f"on each sine of the tracking study whose peak speed is within the valve's "
           f"no-load speed at the full command (K_o): the amplitude ratio of the first "
           f"harmonics is in [{TRACK_RATIO_MIN:g}, {TRACK_RATIO_MAX:g}] and the phase lag at "
           f"most {TRACK_LAG_MAX_DEG:g}° (it follows), and the RMS error at most "
           f"{TRACK_RMS_VS_BEST:g} x the best design's, the baselines included (it is "
           f"competitive); holds when both are true on every such sine, does not hold when "
           f"it follows none, else holds under stated conditions (named)"),
}

#: A value of the structured data behind a verdict (JSON: number, text, true/false, list).
Value = float | int | str | bool | list[float] | None
#: A run as the rules read it: (t [s], y [m], r [m]).
Trace = tuple[FloatArray, FloatArray, FloatArray]
Metrics = Mapping[str, float]


@dataclass(frozen=True, slots=True)
class Claim:
    """One row of the claims table: the verdict, its sentence of evidence, the rule applied,
    its thresholds and the numbers it used (``data``: entity -> field -> value, an entity
    being a controller key, a changed plant or a part of the claim)."""

    id: str
    claim: str
    verdict: str
    evidence: str
    plant: str
    rule: str = ""
    thresholds: dict[str, float] = field(default_factory=dict)
    data: dict[str, dict[str, Value]] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        """The JSON object written to ``claims.json``."""
        return {"id": self.id, "claim": self.claim, "verdict": self.verdict,
                "evidence": self.evidence, "plant": self.plant, "rule": self.rule,
                "thresholds": dict(self.thresholds),
                "data": {k: dict(v) for k, v in self.data.items()}}


def _f(x: float | None, unit: str = "", digits: int = 3) -> str:
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "n/a (never reached)"
    return f"{x:.{digits}g}{unit}"


def alpha_settles(t: FloatArray, alpha: FloatArray, *, tail: float = TAIL_FRACTION,
                  tol: float = ALPHA_MAX_SPREAD) -> tuple[bool, float, float]:
    """Whether alpha is constant (spread <= tol) over the last ``tail`` fraction of the run.

    The default tolerance, 0.01, is one hundredth of alpha's range [0, 1]: a change a plot
    like the paper's Fig. 6 cannot show.

    Returns (settled, final value, spread over the tail).
    """
    t = np.asarray(t, dtype=np.float64)
    a = np.asarray(alpha, dtype=np.float64)
    start = t[0] + (1.0 - tail) * (t[-1] - t[0])
    seg = a[t >= start]
    spread = float(np.max(seg) - np.min(seg)) if seg.size else math.nan
    return bool(spread <= tol), float(a[-1]), spread


def transient_window(pid_filter: float, ts: float) -> float:
    """Start of C3's window after the initial transient [s]: :data:`KICK_TIME_CONSTANTS`
    derivative-filter time constants, ``1/pid_filter`` [s] (N [1/s]) or, for an unfiltered
    derivative (N = inf), the sample time ``ts`` [s] over which its kick lasts."""
    return KICK_TIME_CONSTANTS * max(1.0 / pid_filter, ts)


def command_amplitude(t: FloatArray, u: FloatArray, *, after: float) -> dict[str, float]:
    """The amplitude measures of C3 besides the peak |u| (the metric ``u_max``).

    Parameters
    ----------
    t : array
        Sample times [s].
    u : array
        Commands [-], each held over ``[t[k], t[k+1])`` (zero-order hold).
    after : float
        Start of the window after the initial transient, from ``t[0]`` [s].

    Returns
    -------
    dict
        ``u_max_after``: peak |u| over the samples at ``t - t[0] >= after`` (NaN if none)
        [-]; ``u_rms``: root mean square of u over the run, held as the zero-order hold holds
        it, sqrt(sum u_k^2 (t_k+1 - t_k) / (t[-1] - t[0])) [-].
    """
    t = np.asarray(t, dtype=np.float64)
    u = np.asarray(u, dtype=np.float64)
    late = np.abs(u[(t - t[0]) >= after - 1e-9 * max(after, 1.0)])
    span = float(t[-1] - t[0])
    rms = float(np.sqrt(np.sum(u[:-1] ** 2 * np.diff(t)) / span)) if span > 0 else math.nan
    return {"u_max_after": float(late.max()) if late.size else math.nan, "u_rms": rms}


@dataclass(frozen=True, slots=True)
class Outcome:
    """How one run ends, as C6 and C8 read it."""

    kind: str  #: "settles", "overshoots", "limit cycle", "not settled" or "diverged"
    robust: bool  #: settles, overshoot <= MAX_OVERSHOOT_PCT, no limit cycle, not diverged
    text: str  #: for the evidence
    data: dict[str, Value]  #: the numbers behind it


def response_outcome(m: Metrics, trace: Trace | None, *, duration: float) -> Outcome:
    """Classify a run from its step metrics and, when given, its trace (for a limit cycle):
    :func:`fuzzyservo.analysis.outcome.classify` on this one run, with its text.

    ``m`` needs ``overshoot`` [%] and ``settling_time`` [s] (NaN: not settled) and may hold
    ``diverged`` (nonzero: the state became non-finite); ``duration`` is the run's length [s].
    The step a limit cycle is measured against is ``r[-1] - y[0]`` of the trace.
    """
    os_, ts_ = float(m["overshoot"]), float(m["settling_time"])
    data: dict[str, Value] = {"overshoot": os_, "settling_time": ts_}
    diverged = bool(m.get("diverged", 0.0))
    osc = None
    step = math.nan
    if trace is not None and not diverged:
        t, y, r = trace
        step = float(r[-1] - y[0])
        osc = tail_oscillation(t, y)
        data.update({"tail_peak_to_peak": osc.peak_to_peak, "tail_swings": osc.swings,
                     "tail_period": osc.period, "tail_sustain": osc.sustain})
    tail = (math.nan, math.nan, math.nan) if osc is None else (
        osc.peak_to_peak, float(osc.swings), osc.sustain)
    one = {name: np.array([v]) for name, v in (
        ("overshoot", os_), ("settling_time", ts_), ("tail_peak_to_peak", tail[0]),
        ("tail_swings", tail[1]), ("tail_sustain", tail[2]))}
    kind = str(classify(one, np.array([step]), np.array([diverged]))[0])
    if kind == "diverged":
        text = "diverged"
    elif kind == "limit cycle":
        assert osc is not None  # no tail measured, no limit cycle
        text = (f"limit cycle: +-{_f(0.5e3 * osc.peak_to_peak, ' mm')} "
                f"({_f(50.0 * osc.peak_to_peak / abs(step), ' % of the step')}), period "
                f"{_f(osc.period, ' s')}, over the last {osc.window:.3g} s")
    elif kind == "not settled":
        text = f"not settled by t = {duration:g} s (overshoot {_f(os_, ' %')})"
    elif kind == "overshoots":
        text = f"settles in {_f(ts_, ' s')} but overshoots {_f(os_, ' %')}"
    else:
        text = f"settles in {_f(ts_, ' s')}, overshoot {_f(os_, ' %')}"
    data["outcome"] = kind
    robust = kind == "settles"
    data["robust"] = robust
    return Outcome(kind, robust, text, data)


def _faster(a: Metrics, b: Metrics, key: str) -> bool:
    """a's time metric is strictly smaller than b's; a NaN (never reached) is slowest."""
    x, y = a[key], b[key]
    if math.isnan(x):
        return False
    return math.isnan(y) or x < y


def _robust_thresholds() -> dict[str, float]:
    return {"settle_band_fraction": 0.02, "max_overshoot_pct": MAX_OVERSHOOT_PCT,
            "limit_cycle_tail_fraction": TAIL_FRACTION,
            "limit_cycle_min_peak_to_peak_fraction": LIMIT_CYCLE_MIN_PP,
            "limit_cycle_min_swings": float(LIMIT_CYCLE_MIN_SWINGS),
            "limit_cycle_min_sustain": LIMIT_CYCLE_MIN_SUSTAIN}


def evaluate_claims(
    plant: str,
    metrics: Mapping[str, Metrics],
    labels: Mapping[str, str],
    *,
    stfpi: str,
    fpi: str,
    paper_pids: Sequence[str],
    tuned_pids: Sequence[str],
    alpha_trace: tuple[FloatArray, FloatArray],
    delayed: Metrics,
    delay: float,
    delay_margins: Mapping[str, float],
    variants: Mapping[str, Mapping[str, Metrics]],
    duration: float,
    amplitude_after: float,
    stfpi_equal: str | None = None,
    delay_failures: Mapping[str, Sequence[float]] | None = None,
    stfpi_overshoot_limit: float | None = None,
    delay_sweep: Sequence[float] | None = None,
    delayed_trace: Trace | None = None,
    variant_traces: Mapping[str, Trace] | None = None,
) -> list[Claim]:
    """Give every claim C1-C8 a verdict for one plant.

    Parameters
    ----------
    plant : str
        Plant name written into each row ("linear" or "nonlinear").
    metrics : mapping
        Controller key -> step metrics of its nominal run; the self-tuning fuzzy PI and the
        paper's PIDs also need ``u_max_after`` and ``u_rms`` (:func:`command_amplitude`).
    labels : mapping
        Controller key -> display label.
    stfpi, fpi : str
        Keys of the self-tuning and plain fuzzy PI.
    paper_pids : sequence of str
        Keys of PID (1.2, 1, 0.75) and PID (0.8, 0.55, 0.5), in that order.
    tuned_pids : sequence of str
        Keys of PIDs tuned to the paper's stated constraint.
    alpha_trace : (t, alpha)
        The self-tuning run's α_F(t) [s, -].
    delayed : mapping
        Metrics of the self-tuning run with the hose delay.
    delay : float
        That delay [s].
    delay_margins : mapping
        Controller key -> largest delay [s] of the sweep before its first failure (no 2 %
        settling within the run, or divergence; the sweep does not judge overshoot); NaN
        when it fails already at the first delay.
    variants : mapping
        Changed plant (e.g. "load mass x2") -> controller key -> metrics, gains fixed; a
        ``diverged`` entry (nonzero) marks a diverged run.
    duration : float
        Length of every run [s] (an unsettled response is "not settled by t = duration").
    amplitude_after : float
        Start of C3's window after the initial transient [s] (:func:`transient_window`).
    stfpi_equal : str, optional
        Key of a self-tuning fuzzy PI tuned under the PIDs' constraint, reported beside C1
        as context.
    delay_failures : mapping, optional
        Controller key -> every delay [s] of the sweep at which it fails (the sweep need not
        fail monotonically: a limit cycle can appear at one delay and not at a larger one).
    stfpi_overshoot_limit : float, optional
        Overshoot limit [%] the self-tuning controller was tuned under. When it is within the
        "no overshoot" threshold, C1 holding is partly a consequence of the tuning; C1 then
        fully holds only if the design tuned like the PIDs (``stfpi_equal``) has no overshoot
        either.
    delay_sweep : sequence of float, optional
        The delays of the sweep [s] (to say "every delay" instead of listing them all).
    delayed_trace : (t, y, r), optional
        The run with the hose delay, to find a limit cycle in it (C6) [s, m, m].
    variant_traces : mapping, optional
        Changed plant -> the self-tuning fuzzy PI's run on it (t, y, r), to find a limit cycle
        (C8) [s, m, m]; without one a changed plant is judged on its metrics alone.
    """
    ctx = _Context(plant, metrics, labels, stfpi, list(paper_pids), duration)
    rows = [
        _c1(ctx, stfpi_equal, stfpi_overshoot_limit),
        _c2(ctx, list(tuned_pids)),
        _c3(ctx, amplitude_after),
        _c4(ctx, alpha_trace),
        _c5(ctx, fpi),
        _c6(ctx, delayed, delay, delayed_trace, delay_margins, delay_failures, delay_sweep),
        _c7(ctx),
        _c8(ctx, variants, variant_traces or {}),
    ]
    return rows


@dataclass(frozen=True, slots=True)
class _Context:
    plant: str
    metrics: Mapping[str, Metrics]
    labels: Mapping[str, str]
    stfpi: str
    paper: list[str]
    duration: float

    def claim(self, cid: str, verdict: str, evidence: str, thresholds: dict[str, float],
              data: dict[str, dict[str, Value]]) -> Claim:
        return Claim(cid, CLAIM_TEXTS[cid], verdict, evidence, self.plant, CLAIM_RULES[cid],
                     thresholds, data)

    def row(self, key: str, *names: str) -> dict[str, Value]:
        m = self.metrics[key]
        return {"label": self.labels[key], **{n: float(m[n]) for n in names}}


def _c1(ctx: _Context, stfpi_equal: str | None, limit: float | None) -> Claim:
    st = ctx.metrics[ctx.stfpi]
    os_ = st["overshoot"]
    data = {ctx.stfpi: ctx.row(ctx.stfpi, "overshoot")}
    ev = f"overshoot {_f(os_, ' %')} (no overshoot read as <= {NO_OVERSHOOT_PCT} %)"
    v = HOLDS if os_ <= NO_OVERSHOOT_PCT else NOT_HOLDS
    if limit is not None:
        ev += f", tuned under the constraint overshoot <= {limit:g} %"
        data[ctx.stfpi]["tuned_overshoot_limit"] = float(limit)
    if stfpi_equal is not None:
        eq = ctx.metrics[stfpi_equal]
        data[stfpi_equal] = ctx.row(stfpi_equal, "overshoot", "rise_time", "settling_time")
        ev += (f"; {ctx.labels[stfpi_equal]}: overshoot {_f(eq['overshoot'], ' %')}, "
               f"rise {_f(eq['rise_time'], ' s')}, settle {_f(eq['settling_time'], ' s')}")
        by_tuning = limit is not None and limit <= NO_OVERSHOOT_PCT
        if v == HOLDS and by_tuning and eq["overshoot"] > NO_OVERSHOOT_PCT:
            v = PARTLY
            ev += ("; so it has no overshoot when tuned for none, not as a property of the "
                   "controller")
    return ctx.claim("C1", v, ev, {"no_overshoot_pct": NO_OVERSHOOT_PCT}, data)


def _c2(ctx: _Context, tuned: list[str]) -> Claim:
    st = ctx.metrics[ctx.stfpi]
    pids = ctx.paper + tuned
    beaten = [k for k in pids if _faster(st, ctx.metrics[k], "rise_time")
              and _faster(st, ctx.metrics[k], "settling_time")]
    data = {ctx.stfpi: ctx.row(ctx.stfpi, "rise_time", "settling_time")}
    for k in pids:
        data[k] = {**ctx.row(k, "rise_time", "settling_time"), "slower": k in beaten}
    ev = (f"STFPI rise {_f(st['rise_time'], ' s')}, settle {_f(st['settling_time'], ' s')}; "
          + "; ".join(f"{ctx.labels[k]}: rise {_f(ctx.metrics[k]['rise_time'], ' s')}, "
                      f"settle {_f(ctx.metrics[k]['settling_time'], ' s')}" for k in pids))
    if len(beaten) == len(pids):
        v = HOLDS
    elif all(k in beaten for k in ctx.paper):
        v = PARTLY
        ev += "; faster than the paper's PIDs only, not than: " + ", ".join(
            ctx.labels[k] for k in pids if k not in beaten)
    else:
        v = NOT_HOLDS
    return ctx.claim("C2", v, ev, {"settle_band_fraction": 0.02}, data)


#: C3's measures: metric name -> how the evidence names it ({after} is the window start).
_C3_MEASURES: dict[str, str] = {
    "u_max": "peak |u| over the run",
    "u_max_after": "peak |u| after {after:g} s",
    "u_rms": "RMS of u over the run",
}


def _c3(ctx: _Context, after: float) -> Claim:
    keys = [ctx.stfpi, *ctx.paper]
    data = {k: ctx.row(k, *_C3_MEASURES) for k in keys}
    st = ctx.metrics[ctx.stfpi]
    support: dict[str, Value] = {}
    parts = []
    for name, words in _C3_MEASURES.items():
        support[name] = all(st[name] < ctx.metrics[k][name] for k in ctx.paper)
        parts.append(f"{words.format(after=after)}: STFPI {_f(st[name])}; " + "; ".join(
            f"{ctx.labels[k]}: {_f(ctx.metrics[k][name])}" for k in ctx.paper))
    data["smaller than both paper PIDs"] = support
    yes = [_C3_MEASURES[n].format(after=after) for n, ok in support.items() if ok]
    no = [_C3_MEASURES[n].format(after=after) for n, ok in support.items() if not ok]
    if not no:
        v, said = HOLDS, "Smaller by all three measures"
    elif not yes:
        v, said = NOT_HOLDS, "Smaller by none of the three measures"
    else:
        v, said = PARTLY, f"Smaller by {_join(yes)} only; not by {_join(no)}"
    ev = (". ".join(p[0].upper() + p[1:] for p in parts) + f". {said} (the window from "
          f"{after:g} s leaves out a PID's derivative kick at the step).")
    return ctx.claim("C3", v, ev, {"window_start_s": after,
                                   "kick_time_constants": KICK_TIME_CONSTANTS}, data)


def _c4(ctx: _Context, alpha_trace: tuple[FloatArray, FloatArray]) -> Claim:
    settled, final, spread = alpha_settles(*alpha_trace)
    return ctx.claim(
        "C4", HOLDS if settled else NOT_HOLDS,
        f"α_F ends at {final:.4g}; spread over the last {TAIL_FRACTION * 100:g} % of the "
        f"run {spread:.2g} (constant read as a spread <= {ALPHA_MAX_SPREAD:g})",
        {"tail_fraction": TAIL_FRACTION, "max_spread": ALPHA_MAX_SPREAD},
        {ctx.stfpi: {"label": ctx.labels[ctx.stfpi], "alpha_final": final,
                     "alpha_tail_spread": spread}})


def _c5(ctx: _Context, fpi: str) -> Claim:
    st, fp = ctx.metrics[ctx.stfpi], ctx.metrics[fpi]
    return ctx.claim(
        "C5", HOLDS if _faster(st, fp, "settling_time") else NOT_HOLDS,
        f"settling time (2 %): fuzzy PI {_f(fp['settling_time'], ' s')}, "
        f"self-tuning {_f(st['settling_time'], ' s')}",
        {"settle_band_fraction": 0.02},
        {fpi: ctx.row(fpi, "settling_time"), ctx.stfpi: ctx.row(ctx.stfpi, "settling_time")})


def _c6(ctx: _Context, delayed: Metrics, delay: float, trace: Trace | None,
        margins: Mapping[str, float], failures: Mapping[str, Sequence[float]] | None,
        sweep: Sequence[float] | None) -> Claim:
    st = ctx.metrics[ctx.stfpi]
    out = response_outcome(delayed, trace, duration=ctx.duration)

    def fails(k: str) -> str:
        if failures is None or not failures.get(k):
            return ""
        if sweep is not None and len(failures[k]) == len(sweep):
            return " (fails at every delay of the sweep)"
        ms = ", ".join(f"{d * 1e3:.3g}" for d in failures[k])
        return f" (fails at {ms} ms)"

    text = "; ".join(
        f"{ctx.labels[k]} " + ("fails already without delay" if math.isnan(v)
                               else f"settles up to {v * 1e3:.3g} ms") + fails(k)
        for k, v in margins.items())
    ev = (f"with {delay * 1e3:.3g} ms delay: {out.text} (without: overshoot "
          f"{_f(st['overshoot'], ' %')}, settle {_f(st['settling_time'], ' s')}); delay sweep: "
          f"{text}")
    data: dict[str, dict[str, Value]] = {
        f"{ctx.stfpi}, {delay * 1e3:g} ms delay": {"label": ctx.labels[ctx.stfpi],
                                                    "delay": delay, **out.data}}
    for k, v in margins.items():
        data[k] = {"label": ctx.labels[k], "settles_up_to_delay": v,
                   "fails_at_delays": [float(d) for d in (failures or {}).get(k, [])]}
    if not out.robust:
        v6 = NOT_HOLDS
    else:
        st_margin = margins.get(ctx.stfpi, math.nan)
        others = [m for k, m in margins.items() if k != ctx.stfpi]
        v6 = HOLDS if others and st_margin >= max(others) else PARTLY
        if v6 == PARTLY:
            ev += (f"; robust at {delay * 1e3:.3g} ms, but not the most delay-tolerant "
                   f"controller")
    return ctx.claim("C6", v6, ev, {"delay_s": delay, **_robust_thresholds()}, data)


def _c7(ctx: _Context) -> Claim:
    p1, p2 = ctx.paper[0], ctx.paper[1]
    m1, m2 = ctx.metrics[p1], ctx.metrics[p2]
    settled = not math.isnan(m1["settling_time"])
    sse = float(m1["steady_state_error_fraction"]) if settled else math.nan
    parts = {
        f"{ctx.labels[p1]} overshoot <= {MAX_OVERSHOOT_PCT:g} %":
            bool(m1["overshoot"] <= MAX_OVERSHOOT_PCT),
        f"{ctx.labels[p1]} no steady-state error": settled and abs(sse) <= NO_SSE_FRACTION,
        f"{ctx.labels[p2]} no overshoot": bool(m2["overshoot"] <= NO_OVERSHOOT_PCT),
    }
    sse_text = (f"steady-state error {_f(100 * sse, ' % of step')}" if settled
                else f"not settled by t = {ctx.duration:g} s, so no steady-state error to quote")
    ev = (f"{ctx.labels[p1]}: overshoot {_f(m1['overshoot'], ' %')}, {sse_text}; "
          f"{ctx.labels[p2]}: overshoot {_f(m2['overshoot'], ' %')}")
    n_ok = sum(parts.values())
    v = HOLDS if n_ok == len(parts) else (NOT_HOLDS if n_ok == 0 else PARTLY)
    if v == PARTLY:
        ev += "; holds for: " + ", ".join(p for p, ok in parts.items() if ok)
    data: dict[str, dict[str, Value]] = {
        p1: {**ctx.row(p1, "overshoot", "settling_time"), "settled": settled,
             "steady_state_error_fraction": sse},
        p2: ctx.row(p2, "overshoot", "settling_time"),
        "parts": dict(parts.items()),
    }
    return ctx.claim("C7", v, ev, {"max_overshoot_pct": MAX_OVERSHOOT_PCT,
                                   "no_sse_fraction": NO_SSE_FRACTION,
                                   "no_overshoot_pct": NO_OVERSHOOT_PCT,
                                   "settle_band_fraction": 0.02}, data)


def _c8(ctx: _Context, variants: Mapping[str, Mapping[str, Metrics]],
        traces: Mapping[str, Trace]) -> Claim:
    failed: list[str] = []
    slower: list[str] = []
    robust_text: list[str] = []
    data: dict[str, dict[str, Value]] = {}
    for name, runs in variants.items():
        s = runs[ctx.stfpi]
        out = response_outcome(s, traces.get(name), duration=ctx.duration)
        pids = [k for k in ctx.paper if k in runs]
        fast = all(_faster(s, runs[k], "settling_time") for k in pids)
        data[name] = {**out.data, "faster_than_paper_pids": fast,
                      **{f"settling_time {ctx.labels[k]}": float(runs[k]["settling_time"])
                         for k in pids}}
        if not out.robust:
            failed.append(f"{name}: {out.text}")
        else:
            if not fast:
                slower.append(name)
            robust_text.append(f"{name} ({out.text}, "
                               f"{'faster' if fast else 'not faster'} than both paper PIDs)")
    n = len(variants)
    ev = f"{len(failed)} of {n} changes fail" + (": " + "; ".join(failed) if failed else "")
    if n == 0:
        ev = "no changed plant was simulated, so nothing supports the claim"
    if robust_text:
        ev += ". Robust under: " + "; ".join(robust_text)
    if failed or n == 0:
        v = NOT_HOLDS
    elif slower:
        v = PARTLY
        ev += "; robust under every change, but not faster than the paper's PIDs under: " + (
            ", ".join(slower))
    else:
        v = HOLDS
    return ctx.claim("C8", v, ev + ".", _robust_thresholds(), data)


def summarize(claims: Sequence[Claim],
              comparisons: Mapping[str, tuple[Metrics, Mapping[str, Metrics]]]) -> list[str]:
    """A summary of the verdicts, at most five sentences, computed from them.

    ``claims`` are every plant's; ``comparisons`` maps a plant to the metrics of the
    self-tuning fuzzy PI tuned like the PIDs (same objective and constraints, so the
    comparison is at equal terms) and, by name, the tuned PID-family designs' (named by
    structure: "P (tuned as a 1-DOF PID)", ...). One sentence gives the verdicts per plant,
    one the claims that agree on every plant, and one per plant (at most three) compares
    ITAE, rise and settling time.
    """
    plants = list(dict.fromkeys(c.plant for c in claims))
    out: list[str] = []
    per = []
    for p in plants:
        rows = [c for c in claims if c.plant == p]
        groups = [(HOLDS, ("holds", "hold")),
                  (PARTLY, ("holds only under stated conditions",
                            "hold only under stated conditions")),
                  (NOT_HOLDS, ("does not hold", "do not hold"))]
        bits = []
        for verdict, words in groups:
            ids = [c.id for c in rows if c.verdict == verdict]
            if ids:
                bits.append(f"{len(ids)} {words[len(ids) > 1]} ({', '.join(ids)})")
        per.append(f"on the {p} plant " + _join(bits))
    if per:
        n = len({c.id for c in claims})
        out.append(f"Of the paper's {n} claims, " + "; ".join(per) + ".")
    if len(plants) > 1:
        ids = list(dict.fromkeys(c.id for c in claims))
        def every(verdict: str) -> list[str]:
            return [i for i in ids if all(c.verdict == verdict for c in claims if c.id == i)]
        bits = []
        for verdict, words in ((NOT_HOLDS, ("does not hold on any plant",
                                            "do not hold on any plant")),
                               (HOLDS, ("holds on every plant", "hold on every plant"))):
            same = every(verdict)
            if same:
                bits.append(_join([f"{i} ({CLAIM_SHORT.get(i, i)})" for i in same])
                            + f" {words[len(same) > 1]}")
        if bits:
            s = "; ".join(bits)
            out.append(s[0].upper() + s[1:] + ".")
    for p, (st, tuned) in list(comparisons.items())[:3]:
        if not tuned:
            continue
        names = _join(list(tuned))
        cmp = [_compare(st, tuned, "itae", "ITAE", " m s^2", ("smaller", "larger")),
               _compare(st, tuned, "rise_time", "rise time", " s", ("shorter", "longer")),
               _compare(st, tuned, "settling_time", "2 % settling time", " s",
                        ("shorter", "longer"))]
        out.append(f"On the {p} plant, against the tuned {names}, the self-tuning fuzzy PI "
                   f"tuned like them (ITAE, overshoot <= 10 %) has {_join(cmp)}.")
    return out[:5]


def _compare(st: Metrics, tuned: Mapping[str, Metrics], key: str, words: str, unit: str,
             better_worse: tuple[str, str]) -> str:
    x = st[key]
    ys = [m[key] for m in tuned.values()]
    theirs = " and ".join(_f(y) for y in ys)
    def lt(a: float, b: float) -> bool:  # NaN (never reached) is the largest
        return not math.isnan(a) and (math.isnan(b) or a < b)
    if all(lt(x, y) for y in ys):
        return f"{better_worse[0]} {words} ({_f(x, unit)} against {theirs}{unit})"
    if all(lt(y, x) for y in ys):
        return f"{better_worse[1]} {words} ({_f(x, unit)} against {theirs}{unit})"
    return f"{words} between theirs ({_f(x, unit)} against {theirs}{unit})"


def _join(items: Sequence[str]) -> str:
    if len(items) <= 1:
        return "".join(items)
    return ", ".join(items[:-1]) + " and " + items[-1]

