"""Cross-check of exported .fis files with Octave's fuzzy-logic-toolkit (``make crosscheck``).

Our writer exports systems that cover every MATLAB membership function, operator and
defuzzifier; Octave's own ``readfis`` reads each file and ``evalfis`` evaluates it at random
points inside the input ranges (Octave rejects points outside), with the output universe sampled
on ``--npoints`` points (its default is 101). The table gives, per file, the largest difference
from our exact evaluation as a fraction of the output range, next to the sampling step
range / (npoints - 1), the size of Octave's own error for the integral methods (its centroid
and bisector integrate the sampled aggregate; the maxima methods pick a sample). Sugeno systems
involve no sampling: there the two agree to rounding.

Octave 0.4.6's bisector returns the sample index instead of its abscissa (``crisp_x =
midpoint`` in its defuzz.m); the script maps the index back onto the universe.

Run: ``python benchmarks/crosscheck_octave.py [--npoints 10001] [--points 50]``; needs
``octave`` and ``octave-fuzzy-logic-toolkit`` (Debian), which ``make crosscheck`` installs.
"""

from __future__ import annotations

import argparse
import math
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from fuzzyservo.formats import read_system, write_system
from fuzzyservo.fuzzy import evaluate
from fuzzyservo.fuzzy.system import And, Consequent, FuzzySystem, Is, Or, Rule, Term, Variable
from fuzzyservo.paper import system_file


def _mamdani(name: str, out_terms: tuple[Term, ...], **ops: str) -> FuzzySystem:
    inp = (Term("low", "trapezoid", (-2.0, -1.0, -0.5, 0.2)),
           Term("mid", "gaussian", (0.0, 0.35)),
           Term("high", "bell", (1.0, 0.6, 2.0)))
    inp2 = (Term("neg", "sigmoid", (-0.2, -6.0)), Term("zero", "pi", (-0.8, -0.2, 0.1, 0.7)),
            Term("pos", "gaussian2", (0.3, 0.2, 0.6, 0.4)))
    x1 = Variable("x1", (-1.0, 1.0), inp)
    x2 = Variable("x2", (-1.0, 1.0), inp2)
    y = Variable("y", (0.0, 10.0), out_terms, default=5.0)
    n = len(out_terms)
    rules = []
    for i in range(3):
        for j in range(3):
            ante = And((Is(0, i), Is(1, j))) if (i + j) % 2 == 0 else Or((Is(0, i),
                                                                          Is(1, j, True)))
            rules.append(Rule(ante, (Consequent(0, (i + 2 * j) % n),),
                              weight=1.0 if (i + j) % 3 else 0.7))
    return FuzzySystem(name=name, inputs=(x1, x2), outputs=(y,), rules=tuple(rules), **ops)


def systems() -> dict[str, FuzzySystem]:
    """The systems exported and cross-checked, by file stem."""
    pl = (Term("a", "triangle", (0.0, 1.5, 4.0)), Term("b", "trapezoid", (2.0, 4.0, 5.0, 7.5)),
          Term("c", "triangle", (6.0, 8.0, 10.0)), Term("d", "triangle", (4.5, 5.0, 5.5)))
    smooth = (Term("a", "gaussian", (2.0, 1.0)), Term("b", "bell", (5.0, 1.2, 3.0)),
              Term("c", "sigmoid", (8.0, 3.0)), Term("d", "dsigmoid", (3.0, 4.0, 4.0, 6.0)),
              Term("e", "psigmoid", (4.0, 3.0, -3.0, 7.0)), Term("f", "s", (6.0, 9.0)),
              Term("g", "z", (1.0, 3.0)), Term("h", "pi", (2.0, 4.0, 5.0, 8.0)),
              Term("i", "gaussian2", (3.0, 0.5, 6.0, 1.0)))
    out: dict[str, FuzzySystem] = {}
    for d in ("centroid", "bisector", "mom", "som", "lom"):
        out[f"pl-{d}"] = _mamdani(f"pl_{d}", pl, defuzzifier=d)
    out["pl-prod-sum"] = _mamdani("pl_prod_sum", pl, and_op="product", or_op="probor",
                                  implication="product", aggregation="sum")
    out["pl-probor"] = _mamdani("pl_probor", pl, aggregation="probor")
    out["smooth-centroid"] = _mamdani("smooth_centroid", smooth)
    out["smooth-bisector"] = _mamdani("smooth_bisector", smooth, defuzzifier="bisector",
                                      implication="product")
    x1 = Variable("x1", (-1.0, 1.0), (Term("n", "triangle", (-2.0, -1.0, 1.0)),
                                       Term("p", "gaussian", (1.0, 0.8))))
    x2 = Variable("x2", (0.0, 2.0), (Term("lo", "z", (0.0, 2.0)),
                                      Term("hi", "s", (0.0, 2.0))))
    z = Variable("z", (-5.0, 5.0), (Term("c1", "constant", (-3.0,)),
                                     Term("l1", "linear", (2.0, -1.0, 0.5)),
                                     Term("l2", "linear", (-1.0, 3.0, 0.0))), default=0.0,
                 clip=False)
    rules = (Rule(And((Is(0, 0), Is(1, 0))), (Consequent(0, 0),)),
             Rule(And((Is(0, 1), Is(1, 0))), (Consequent(0, 1),), weight=0.5),
             Rule(Or((Is(0, 0), Is(1, 1))), (Consequent(0, 2),)))
    for d in ("wtaver", "wtsum"):
        out[f"sugeno-{d}"] = FuzzySystem(name=f"sugeno_{d}", kind="sugeno", inputs=(x1, x2),
                                         outputs=(z,), rules=rules, defuzzifier=d)
    return out


# Octave's toolkit 0.4.6 names MATLAB's probor "algebraic_sum" and has no probor.m: an alias
# with MATLAB's name, on the path of the run only.
_PROBOR = """function retval = probor (x, y)
  if (nargin == 1)
    retval = algebraic_sum (x);
  else
    retval = algebraic_sum (x, y);
  endif
endfunction
"""

_OCTAVE = """
pkg load fuzzy-logic-toolkit
addpath('{path}');
fis = readfis('{fis}');
x = dlmread('{inp}', ',');
y = evalfis(x, fis, {npoints});
dlmwrite('{out}', y, 'precision', '%.17g');
"""


def octave_eval(fis: Path, x: np.ndarray, npoints: int) -> np.ndarray:
    """Octave's evalfis of ``fis`` at the rows of ``x``."""
    with tempfile.TemporaryDirectory() as d:
        inp, out, script = Path(d) / "x.csv", Path(d) / "y.csv", Path(d) / "run.m"
        np.savetxt(inp, x, delimiter=",", fmt="%.17g")
        (Path(d) / "probor.m").write_text(_PROBOR)
        script.write_text(_OCTAVE.format(path=d, fis=fis, inp=inp, out=out, npoints=npoints))
        proc = subprocess.run(["octave", "--no-gui", "--quiet", "--no-window-system",
                               str(script)], capture_output=True, text=True, timeout=3600,
                              check=False)
        if not out.exists():
            raise RuntimeError(f"octave failed on {fis.name}: {proc.stdout} {proc.stderr}")
        return np.atleast_2d(np.loadtxt(out, delimiter=",")).reshape(x.shape[0], -1)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--npoints", type=int, default=10_001)
    parser.add_argument("--points", type=int, default=50)
    args = parser.parse_args()
    if shutil.which("octave") is None:
        print("octave is missing: run `make crosscheck` (installs octave and "
              "octave-fuzzy-logic-toolkit)", file=sys.stderr)
        return 2
    rng = np.random.default_rng(20261130)
    rows = []
    worst = 0.0
    with tempfile.TemporaryDirectory() as d:
        files = {f"paper-{r}": system_file(r, "fis") for r in ("du", "alpha")}
        for stem, s in systems().items():
            files[stem] = Path(d) / f"{stem}.fis"
            write_system(s, files[stem])
        for stem, path in files.items():
            s = read_system(path)
            lo = np.array([v.range[0] for v in s.inputs])
            hi = np.array([v.range[1] for v in s.inputs])
            x = lo + (hi - lo) * rng.uniform(0.0, 1.0, (args.points, len(s.inputs)))
            ours = evaluate(s, x)
            theirs = octave_eval(path, x, args.npoints)
            if s.defuzzifier == "bisector":
                # toolkit 0.4.6's defuzz.m returns the bisector's sample index ("crisp_x =
                # midpoint"), not its abscissa: map the 1-based index onto the universe
                lo_o = np.array([v.range[0] for v in s.outputs])
                hi_o = np.array([v.range[1] for v in s.outputs])
                theirs = lo_o + (theirs - 1.0) * (hi_o - lo_o) / (args.npoints - 1)
            span = np.array([v.range[1] - v.range[0] for v in s.outputs])
            ok = np.isfinite(theirs)
            err = float(np.max(np.abs(ours - theirs)[ok] / np.broadcast_to(span, ours.shape)[ok]))
            step = 1.0 / (args.npoints - 1)
            sampled = s.kind == "mamdani"
            rows.append((stem, s.kind, s.defuzzifier, err, step if sampled else 0.0,
                         int((~ok).sum())))
            if sampled and err > 2 * step:
                worst = max(worst, err / step)
            if not sampled and err > 1e-12:
                worst = max(worst, math.inf)
    print(f"Octave fuzzy-logic-toolkit evalfis (npoints {args.npoints}) vs fuzzyservo exact, "
          f"{args.points} random points per file")
    print(f"{'file':<18} {'kind':<8} {'defuzz':<9} {'max |diff| / range':>19} "
          f"{'sampling step':>14} {'nan':>4}")
    for stem, kind, dz, err, step, nan in rows:
        print(f"{stem:<18} {kind:<8} {dz:<9} {err:>19.3e} {step:>14.3e} {nan:>4}")
    if worst:
        print("some file differs by more than twice Octave's sampling step (or a Sugeno file "
              "by more than rounding): see above")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
