"""``fuzzyservo tune``: automatic step-response tuning of a controller on the servo.

``fuzzyservo tune --controller NAME --plant NAME --objective itae --max-overshoot 10
[--max-sse 0.2] [--max-u 1] [--seed 0] [--set paper] [--param ...] [--step 0.1]
[--duration 10] [--ts 0.001] [--delay S|hose] --out gains.toml [--resume]``: any controller and
plant of the registry; what is searched is the controller's registry entry.

Robust tuning: ``fuzzyservo tune --robust SPEC.toml --controller NAME [--statistic
worst|mean|pNN] [--objective itae] [--max-overshoot 10] ... --out gains.toml [--resume]``
tunes one design on every point of a sweep spec (a fixed set of sampled plants, delays and
sensor noise; at most :data:`~fuzzyservo.analysis.robust.MAX_ROBUST_POINTS`): the objective
is the statistic over the set (default ``worst``, the largest), and every constraint must
hold on every plant. The plant kind, parameter set and overrides, start, step, duration,
sample time and delay are the spec's (``--plant``, ``--set``, ``--params``, ``--param``,
``--start``, ``--step``, ``--duration``, ``--ts`` and ``--delay`` are refused); its
``[[controllers]]`` are not tuned. The gains file records the set (spec path, SHA-256 of the
set, points, statistic) and the spec's nominal plant, which ``fuzzyservo simulate --gains``
runs; its metrics are the worst case over the set (the objective: the statistic, and
``<objective>_worst``).
docs/sweep.md, "Robust tuning".

A progress bar per search stage goes to stderr. Each search stops when it has converged
(``--patience``, ``--rtol``) or at ``--maxiter`` generations (then a warning says it did not
converge); a gain that ends on a bound of its box is named in a warning. Ctrl-C writes the
search state to ``OUT.partial.npz`` next to ``--out``; ``--resume`` with the same options
continues from it and gives the uninterrupted run's result, bit for bit; a resume with any
other setting is refused, naming it.

Everything is checked before the search starts: ``--out`` (its folder exists and is writable,
it is not a folder nor the ``--params`` file), the run (``--duration``/``--ts`` at most
:data:`~fuzzyservo.sim.closed_loop.MAX_SAMPLES` samples, ``--delay`` at most ``--duration``,
start + ``--step`` within the stroke, the transducer resolution no coarser than the step),
``--popsize`` and ``--maxiter`` (at most :data:`~fuzzyservo.analysis.autotune.MAX_POPSIZE` and
:data:`~fuzzyservo.analysis.autotune.MAX_MAXITER`) and the checkpoint of ``--resume``.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from pathlib import Path
from typing import Any

from .._io import check_output_path
from ..analysis.autotune import (
    DEFAULT_MAXITER,
    DEFAULT_RESTARTS,
    MAX_MAXITER,
    MAX_POPSIZE,
    MAX_RESTARTS,
    RESTART_TOLERANCE,
    Checkpoint,
    TuningProgress,
    TuningSetup,
    tune_controller,
)
from ..analysis.robust import MAX_ROBUST_POINTS, RobustSet, parse_statistic, worst_name
from ..analysis.tuning import OBJECTIVES, StopRule, TuningConstraints
from ..errors import ParameterError
from ..files import checkpoint_path, load_checkpoint, save_checkpoint, write_gains_toml
from ..plant import ServoParams
from ..registry import controller_names
from ..run import RunSpec
from . import HELP
from ._plantargs import (
    add_plant_arguments,
    overrides_from_args,
    params_from_args,
    params_given,
    set_name,
)
from ._runargs import (
    add_delay_argument,
    add_plant_choice,
    add_system_arguments,
    delay_from_args,
    systems_from_args,
    systems_record,
)

__all__ = ["register", "run"]

DEFAULT_STOP = StopRule()

#: Defaults of the run options a robust tuning takes from its spec instead (None on the
#: command line, so that one given with --robust is refused): :class:`TuningSetup`'s.
RUN_DEFAULTS: dict[str, Any] = {name: TuningSetup.__dataclass_fields__[name].default
                                for name in ("plant", "step", "duration", "ts", "start")}


def register(subparsers: Any) -> None:
    """Add the ``tune`` subcommand."""
    p = subparsers.add_parser(
        "tune", help=HELP["tune"],
        description="Tune the gains of a controller (any kind of the registry: --controller) "
                    "on a plant model by differential evolution over "
                    "the batched simulator, and write them to a gains file (TOML) that "
                    "'fuzzyservo simulate --gains FILE' runs. With --robust SPEC.toml, tune "
                    "one design on every point of a sweep spec: a statistic of the objective "
                    "over the set, the constraints on every plant (docs/sweep.md, 'Robust "
                    "tuning').")
    names = controller_names()
    p.add_argument("--controller", required=True, choices=names, metavar="NAME",
                   help=f"controller: {', '.join(names)}")
    add_plant_choice(p, None, shown=RUN_DEFAULTS["plant"])
    p.add_argument("--objective", default="itae", choices=OBJECTIVES, metavar="NAME",
                   help=f"objective: {', '.join(OBJECTIVES)} (default itae)")
    p.add_argument("--max-overshoot", type=float, default=10.0, metavar="PERCENT",
                   help="largest allowed overshoot in percent (default 10)")
    p.add_argument("--max-sse", type=float, default=0.2, metavar="PERCENT",
                   help="largest allowed |steady-state error| in percent of the step "
                        "(default 0.2)")
    p.add_argument("--max-u", type=float, default=None, metavar="U",
                   help="largest allowed |u| as a fraction of the rated command (default none)")
    p.add_argument("--seed", type=int, default=0, help="seed of the search (default 0)")
    p.add_argument("--popsize", type=int, default=10,
                   help=f"population multiplier, 2 to {MAX_POPSIZE}: popsize x (searched "
                        f"gains) runs per generation (default 10)")
    p.add_argument("--maxiter", type=int, default=DEFAULT_MAXITER,
                   help=f"generation limit of each search stage, 1 to {MAX_MAXITER} (default "
                        f"{DEFAULT_MAXITER}); a search normally stops before, when it has "
                        f"converged (--patience, --rtol)")
    p.add_argument("--patience", type=int, default=DEFAULT_STOP.patience, metavar="N",
                   help=f"stopping rule: converged when the best cost improved by at most "
                        f"--rtol over N generations (default {DEFAULT_STOP.patience})")
    p.add_argument("--rtol", type=float, default=DEFAULT_STOP.rtol, metavar="R",
                   help=f"stopping rule's relative improvement (default {DEFAULT_STOP.rtol:g})")
    p.add_argument("--restarts", type=int, default=DEFAULT_RESTARTS, metavar="N",
                   help=f"independent searches per stage, 1 to {MAX_RESTARTS}; the best is kept "
                        f"and their disagreement reported (default {DEFAULT_RESTARTS})")
    p.add_argument("--spread", type=float, default=DEFAULT_STOP.spread, metavar="S",
                   help=f"stopping rule: the population's median cost within S (relative) of "
                        f"the best (default {DEFAULT_STOP.spread:g})")
    p.add_argument("--step", type=float, default=None, metavar="M",
                   help=f"reference step [m] (default {RUN_DEFAULTS['step']:g})")
    p.add_argument("--duration", type=float, default=None, metavar="S",
                   help="simulated time per run [s], at least 10 samples and at most "
                        f"10 million (default {RUN_DEFAULTS['duration']:g})")
    p.add_argument("--ts", type=float, default=None, metavar="S",
                   help=f"controller sample period [s] (default {RUN_DEFAULTS['ts']:g})")
    add_delay_argument(p)
    p.add_argument("--start", type=float, default=None, metavar="FRACTION",
                   help=f"start position as a fraction of the stroke (default "
                        f"{RUN_DEFAULTS['start']:g})")
    p.add_argument("--robust", type=Path, default=None, metavar="SPEC.toml",
                   help=f"robust tuning: tune on every point of this sweep spec (at most "
                        f"{MAX_ROBUST_POINTS}; plant, parameters, step, duration, ts, start "
                        "and delay are the spec's, so --plant, --set, --params, --param, "
                        "--step, --duration, --ts, --start and --delay are refused; its "
                        "[[controllers]] are not tuned)")
    p.add_argument("--statistic", default=None, metavar="worst|mean|pNN",
                   help="with --robust: the statistic of the objective over the set that is "
                        "minimised: worst (the largest; default), mean, or a percentile such "
                        "as p90; the constraints hold on every plant whatever it is")
    p.add_argument("--out", type=Path, required=True, metavar="FILE.toml",
                   help="gains file to write (checked before the search: its folder must "
                        "exist, and it must not be the --params file)")
    p.add_argument("--resume", action="store_true",
                   help="continue from OUT.partial.npz left by an interrupted run")
    p.add_argument("--no-polish", dest="polish", action="store_false",
                   help="skip the Nelder-Mead polish after each search stage")
    p.add_argument("--quiet", action="store_true", help="no progress output")
    add_system_arguments(p)
    add_plant_arguments(p)
    p.set_defaults(handler=run)


def _given(args: argparse.Namespace, name: str) -> Any:
    """The value of run option ``name`` given, else its default (:data:`RUN_DEFAULTS`)."""
    value = getattr(args, name)
    return RUN_DEFAULTS[name] if value is None else value


def _setup(args: argparse.Namespace, params: ServoParams,
           systems: dict[str, Any] | None = None) -> TuningSetup:
    """The tuning the options describe: the run of each candidate (a :class:`RunSpec`) and
    how to search."""
    constraints = TuningConstraints.from_limits(max_overshoot=args.max_overshoot,
                                                max_sse_percent=args.max_sse,
                                                max_u=args.max_u)
    overrides = tuple(overrides_from_args(args).items()) if args.robust is None else ()
    record = systems_record(systems)
    step = float(_given(args, "step"))
    if not (math.isfinite(step) and step > 0.0):  # (before it is written as a reference)
        raise ParameterError(f"TuningSetup.step must be finite and > 0, got {step!r}")
    run = RunSpec(controller=args.controller, plant=_given(args, "plant"),
                  param_set=set_name(args), overrides=overrides, start=_given(args, "start"),
                  reference=f"step:{step!r}",
                  duration=_given(args, "duration"), ts=_given(args, "ts"),
                  delay=delay_from_args(args.delay, params),
                  systems=tuple((role, source) for role, source, _ in record))
    return TuningSetup.for_run(
        run, systems=record, objective=args.objective, constraints=constraints,
        seed=args.seed, popsize=args.popsize, maxiter=args.maxiter, patience=args.patience,
        rtol=args.rtol, spread=args.spread, restarts=args.restarts, polish=args.polish)


class _Progress:
    """tqdm bar per stage on stderr; one line per stage when stderr is not a terminal."""

    def __init__(self, setup: TuningSetup, quiet: bool) -> None:
        self.setup = setup
        self.quiet = quiet
        self.latest: Checkpoint | None = None
        self.bar: Any = None
        self.stage = ""
        self.plain = os.environ.get("CI", "").lower() == "true" or not sys.stderr.isatty()

    def __call__(self, p: TuningProgress) -> None:
        self.latest = p.checkpoint
        runs = p.n_evaluations * (1 if self.setup.robust is None else self.setup.robust.points)
        if self.quiet:
            return
        label = p.stage + (f" {p.restart + 1}/{p.restarts}" if p.restarts > 1 else "")
        if label != self.stage:
            self.close()
            self.stage = label
            if not self.plain:
                from tqdm import tqdm

                # counts on from a resumed generation; the bar ends early when converged
                self.bar = tqdm(total=p.max_generations, initial=p.generation,
                                desc=f"tune {label}", unit="gen", file=sys.stderr,
                                leave=True)
        if self.bar is not None:
            self.bar.set_postfix(best=f"{p.best_cost:.6g}", runs=runs)
            self.bar.n = p.generation
            self.bar.refresh()
        elif p.generation % 10 == 0 or p.generation == 1:
            print(f"tune {label}: generation {p.generation}/{p.max_generations}, "
                  f"best cost {p.best_cost:.4g}, {runs} runs", file=sys.stderr,
                  flush=True)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
            self.bar = None


#: Options a robust tuning takes from its spec, by the attribute they set.
_FROM_SPEC = (("plant", "--plant"), ("step", "--step"), ("duration", "--duration"),
              ("ts", "--ts"), ("start", "--start"), ("delay", "--delay"))


def _robust(args: argparse.Namespace, systems: dict[str, Any] | None
            ) -> tuple[TuningSetup, ServoParams, RobustSet]:
    """The setup, nominal parameters and set of plants of ``--robust SPEC``.

    Raises
    ------
    ParameterError
        An option the spec gives was given too (all of them named, in one line), a bad
        statistic, a spec of too many points or with an invalid point.
    """
    from ..sweep.robust import robust_set, robust_setup
    from ..sweep.spec import load_spec

    given = [flag for name, flag in _FROM_SPEC if getattr(args, name) is not None]
    if params_given(args):
        given += [flag for flag, v in (("--set", args.param_set), ("--params", args.param_file),
                                       ("--param", args.param_overrides)) if v]
    if given:
        raise ParameterError(f"--robust takes the plant, parameters, step, duration, ts, "
                             f"start and delay from {str(args.robust)!r}: drop "
                             f"{', '.join(given)}")
    statistic = parse_statistic("worst" if args.statistic is None else args.statistic)
    spec = load_spec(args.robust)
    rset, record = robust_set(spec, source=str(args.robust), statistic=statistic)
    params = spec.nominal
    return robust_setup(spec, _setup(args, params, systems), record), params, rset


def run(args: argparse.Namespace) -> int:
    """Handler of ``fuzzyservo tune``."""
    inputs = tuple(p for p in (args.param_file, args.robust) if p is not None)
    out: Path = check_output_path(args.out, option="--out", inputs=inputs)
    systems = systems_from_args(args, args.controller)
    rset: RobustSet | None = None
    if args.robust is not None:
        setup, params, rset = _robust(args, systems)
    else:
        if args.statistic is not None:
            raise ParameterError("--statistic applies to a robust tuning: add --robust "
                                 "SPEC.toml")
        params = params_from_args(args)
        setup = _setup(args, params, systems)
    ckpt_file = checkpoint_path(out)
    resume = load_checkpoint(ckpt_file) if args.resume else None
    progress = _Progress(setup, args.quiet)
    try:
        try:
            tuned = tune_controller(setup, params, progress=progress, resume=resume,
                                    systems=systems, robust=rset)
        except ParameterError as exc:
            if resume is not None and str(exc).startswith("the checkpoint"):
                raise ParameterError(f"{str(ckpt_file)!r}: {exc}") from None
            raise
    except KeyboardInterrupt:
        progress.close()
        if progress.latest is None:  # nothing to save yet: the CLI's one line says so
            raise
        save_checkpoint(ckpt_file, progress.latest)
        restart = (f" (search {progress.latest.restart + 1} of {setup.restarts})"
                   if setup.restarts > 1 else "")
        print(f"fuzzyservo: interrupted; search state saved to {ckpt_file} after "
              f"generation {progress.latest.generation} of stage {progress.latest.stage}"
              f"{restart} "
              f"(continue with the same options and --resume)", file=sys.stderr)
        return 130
    progress.close()
    write_gains_toml(out, tuned)
    if args.resume and ckpt_file.exists():
        ckpt_file.unlink()
    gains = ", ".join(f"{k}={v:.6g}" for k, v in tuned.gains.items())
    m = tuned.metrics
    what = tuned.structure
    named = tuned.controller + (f" (a {what} design)" if what in ("P", "PI", "PD") else "")
    if setup.robust is None:
        print(f"{named} on the {setup.plant} plant: {gains}")
        objective = f"{setup.objective}={tuned.objective_value:.6g}"
        runs = f"{tuned.n_evaluations} runs"
    else:
        runs = (f"{tuned.n_evaluations} candidates x {setup.robust.points} plants = "
                f"{tuned.n_evaluations * setup.robust.points} runs")
        print(f"{named} on {setup.robust.points} {setup.plant} plants of {setup.robust.source}"
              f": {gains}")
        print("worst case over the set: ", end="")
        objective = f"{setup.objective} {setup.robust.statistic}={tuned.objective_value:.6g}"
        if setup.robust.statistic != "worst":
            objective += f", {setup.objective} worst={m[worst_name(setup.objective)]:.6g}"
    print(f"{objective}, overshoot={m['overshoot']:.3g} %, "
          f"rise_time={m['rise_time']:.4g} s, settling_time={m['settling_time']:.4g} s, "
          f"u_max={m['u_max']:.3g}, feasible={'yes' if tuned.feasible else 'no'}, "
          f"converged={'yes' if tuned.converged else 'no'}, {tuned.generations} generations, "
          f"{runs} in {tuned.elapsed:.1f} s -> {out}")
    box = setup.search_bounds()
    for name, side in tuned.at_bounds.items():
        i = box.names.index(name)
        edge = box.lowest()[i] if side == "lower" else box.upper[i]
        off = box.zero[i] and side == "lower"
        print(f"fuzzyservo: warning: {name} ended on its {side} bound ({edge:g})"
              + (": the term is switched off" if off else
                 ": the optimum may lie on or beyond the box's edge"), file=sys.stderr)
    for st in tuned.stages:
        if st.restart_spread > RESTART_TOLERANCE:
            print(f"fuzzyservo: warning: the {setup.restarts} searches of stage {st.name} "
                  f"ended {100 * st.restart_spread:.3g} % apart in cost: it has several "
                  f"optima and the best found may not be the global one (raise --restarts "
                  f"or --popsize)", file=sys.stderr)
    if not tuned.converged:
        print(f"fuzzyservo: warning: the search did not converge within --maxiter "
              f"{setup.maxiter} generations per stage (stopping rule: best cost improving "
              f"by at most {setup.rtol:g} over {setup.patience} generations); raise "
              f"--maxiter", file=sys.stderr)
    if not tuned.feasible:
        every = " on every plant of the set" if setup.robust is not None else ""
        print(f"fuzzyservo: no gains found that meet the constraints{every}; the best found "
              f"are written to {out} (loosen a constraint or widen the search)",
              file=sys.stderr)
        return 1
    return 0
