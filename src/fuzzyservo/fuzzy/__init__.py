"""fuzzyservo.fuzzy: the fuzzy model (FuzzySystem), its membership shapes, and one exact engine.

- :mod:`.system`: the model, frozen data (variables, terms, rules, operators) and its builders
  (:meth:`Variable.uniform`, :meth:`FuzzySystem.from_table`);
- :mod:`.shapes`: the table of membership shapes every module reads;
- :mod:`.engine`: :func:`pack` (chooses the evaluation path) and :func:`evaluate`, the same
  compiled code the controllers' loops run; :mod:`.kernels` (uniform grid), :mod:`.partition`
  and :mod:`.general` are its paths;
- :mod:`.loop`: a system checked and packed for a controller's loop.
"""

from __future__ import annotations

from .engine import PackedSystem, evaluate, pack
from .general import membership
from .kernels import eval_uniform_batch, eval_uniform_grid, eval_uniform_pair
from .loop import LoopSystem, loop_system, system_digest
from .shapes import SHAPE_TABLE, Shape
from .system import And, Consequent, FuzzySystem, Is, Not, Or, Rule, Term, Variable

__all__ = [
    "SHAPE_TABLE",
    "And",
    "Consequent",
    "FuzzySystem",
    "Is",
    "LoopSystem",
    "Not",
    "Or",
    "PackedSystem",
    "Rule",
    "Shape",
    "Term",
    "Variable",
    "eval_uniform_batch",
    "eval_uniform_grid",
    "eval_uniform_pair",
    "evaluate",
    "loop_system",
    "membership",
    "pack",
    "system_digest",
]
