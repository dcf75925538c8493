"""A general fuzzy system in a controller's loop: two inputs (e, Δe), the first output used.

:func:`loop_system` checks a :class:`~fuzzyservo.fuzzy.system.FuzzySystem` for that role and
packs it (:func:`fuzzyservo.fuzzy.engine.pack`); the result goes wherever the paper's systems
go (``systems={"du": ...}`` of the registry, ``FuzzyPIController.from_systems``). The compiled
loops then evaluate it point by point, exactly as :func:`fuzzyservo.fuzzy.engine.evaluate`
does (the uniform grid for a system of that form, such as the paper's read from its file; the
general evaluator otherwise).

Scaling (docs/fuzzy-files.md, "In the loop"): the system is evaluated at (K_e e, K_Δe Δe) in the
universes its file states, and its output is multiplied by K_Δu (and α): with the paper's
normalised universes [-1, 1] this is the paper's controller; a file in physical units takes the
gains that convert to them (K_e = 1000 for an e universe in millimetres).

No rule firing would leave the controller without a value. A system is accepted for a loop if
its output's default is finite (FCL ``DEFAULT``, FLL ``default``, the middle of the range for
.fis files), or if some rule provably fires everywhere: every rule names every input (a rule
table with no empty cell, AND of plain clauses) and the open supports of each input's terms cover
its range, or a given ``no_rule_value`` replaces a NaN default.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
from dataclasses import dataclass

from .._typing import FloatArray, IntArray
from ..errors import ParameterError
from .engine import PackedSystem, pack
from .shapes import support
from .system import And, FuzzySystem, Is, Term

__all__ = ["LoopSystem", "always_fires", "loop_system", "system_digest"]


def _covers(terms: tuple[Term, ...], lo: float, hi: float) -> bool:
    """True if the terms' open supports cover [lo, hi] (a conservative test: a point covered
    only by a closed end of a support, e.g. a rectangle's edge, counts as uncovered)."""
    sup = sorted(s for s in (support(t.shape, t.params) for t in terms) if s is not None)
    merged: list[list[float]] = []
    for a, b in sup:
        if merged and a < merged[-1][1]:
            merged[-1][1] = max(merged[-1][1], b)
        else:
            merged.append([a, b])
    return any(a < lo and b > hi for a, b in merged)


def always_fires(system: FuzzySystem) -> bool:
    """True if, for every input point, some rule naming output 0 has a positive strength.

    A sufficient condition, checked exactly: every (input term combination) cell of the rule
    table holds a rule with an output-0 consequent and weight > 0, every rule is an AND of
    plain clauses naming every input once, and each input's terms cover its range (clipped
    inputs) with their open supports."""
    n_in = len(system.inputs)
    cells: set[tuple[int, ...]] = set()
    for r in system.rules:
        a = r.antecedent
        clauses = [a] if isinstance(a, Is) else list(a.operands) if isinstance(a, And) else []
        if len(clauses) != n_in or not all(isinstance(c, Is) and not c.negated for c in clauses):
            return False
        vars_ = {c.variable: c.term for c in clauses if isinstance(c, Is)}
        if len(vars_) != n_in:
            return False
        if r.weight > 0.0 and any(c.variable == 0 for c in r.consequents):
            cells.add(tuple(vars_[i] for i in range(n_in)))
    total = math.prod(len(v.terms) for v in system.inputs)
    if len(cells) != total:
        return False
    return all(v.clip and _covers(v.terms, *v.range) for v in system.inputs)


def system_digest(system: FuzzySystem) -> str:
    """SHA-256 of a system's values (its repr, which is exact for floats): names a system in
    cache keys, checkpoints and gains files."""
    return hashlib.sha256(repr(dataclasses.replace(system, notes=())).encode()).hexdigest()


@dataclass(frozen=True, slots=True, eq=False)
class LoopSystem:
    """A two-input fuzzy system packed for the controllers' loops (see :func:`loop_system`).

    Attributes
    ----------
    packed : PackedSystem
        The packed system (output 0 is the one used; :func:`fuzzyservo.fuzzy.engine.pack`).
    source : str
        Where it came from (a file name), for messages and records.
    digest : str
        :func:`system_digest` of the system.
    """

    packed: PackedSystem  #: the packed system
    source: str  #: file name or description
    digest: str  #: SHA-256 of the system's values

    @property
    def system(self) -> FuzzySystem:
        """The fuzzy system."""
        return self.packed.system

    def kernel_args(self) -> tuple[IntArray, FloatArray]:
        """``(rules, lims)`` for the controllers' loops: the uniform-grid tables or the
        general evaluator's arrays (:meth:`PackedSystem.kernel_args`)."""
        return self.packed.kernel_args()

    def describe(self, role: str = "du") -> str:
        """One line: the inputs' and the output's universes and the gains that scale them
        (``role`` "du": the output times K_Δu is the command increment; "alpha": the output
        multiplies K_Δu)."""
        s = self.system
        (e, de), out = s.inputs, s.outputs[0]
        use = "x K_du = command increment" if role == "du" else "= alpha, multiplies K_du"
        return (f"{self.source}: {e.name} in [{e.range[0]:g}, {e.range[1]:g}] = K_e e, "
                f"{de.name} in [{de.range[0]:g}, {de.range[1]:g}] = K_de de, "
                f"{out.name} in [{out.range[0]:g}, {out.range[1]:g}] ({use})")


def loop_system(system: FuzzySystem, *, source: str = "<system>",
                no_rule_value: float | None = None, grid: bool = True) -> LoopSystem:
    """Check ``system`` for a controller's loop and pack it.

    Parameters
    ----------
    system : FuzzySystem
        Two inputs (e, Δe, in this order); its first output is used.
    source : str
        Name shown in messages (the file).
    no_rule_value : float, optional
        Output when no rule fires, replacing a NaN default [unit of the output].
    grid : bool
        Let :func:`~fuzzyservo.fuzzy.engine.pack` take the uniform-grid path when the system
        has its form (False: always the general evaluator).

    Raises
    ------
    ParameterError
        Not two inputs, or a NaN default (no value when no rule fires) for a rule base that
        does not provably fire everywhere, and no ``no_rule_value``.
    """
    if not isinstance(system, FuzzySystem):
        raise ParameterError(f"expected a FuzzySystem, got {type(system).__name__}")
    if len(system.inputs) != 2:
        raise ParameterError(
            f"{source}: a controller's fuzzy system takes two inputs (e, de), this one has "
            f"{len(system.inputs)} ({', '.join(v.name for v in system.inputs)})")
    out = system.outputs[0]
    if no_rule_value is not None:
        if not math.isfinite(no_rule_value):
            raise ParameterError(f"no_rule_value must be finite, got {no_rule_value!r}")
        if math.isnan(out.default):
            outs = (dataclasses.replace(out, default=float(no_rule_value)),
                    *system.outputs[1:])
            system = dataclasses.replace(system, outputs=outs)
    elif math.isnan(out.default) and not always_fires(system):
        raise ParameterError(
            f"{source}: output {out.name!r} has no value for when no rule fires (default NaN) "
            f"and its rules do not provably cover every (e, de): set a default in the file "
            f"(FCL DEFAULT, FLL default) or pass --no-rule-value")
    return LoopSystem(packed=pack(system, grid=grid), source=source,
                      digest=system_digest(system))
