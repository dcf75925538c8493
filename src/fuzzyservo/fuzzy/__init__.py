"""fuzzyservo.fuzzy: membership functions, rule bases, Mamdani systems, compiled kernels."""

from __future__ import annotations

from .kernels import eval_uniform_batch, eval_uniform_grid, eval_uniform_pair
from .mamdani import MamdaniSpec, MamdaniSystem
from .membership import (
    Bell,
    Gaussian,
    LeftShoulder,
    MembershipFunction,
    RightShoulder,
    Trapezoid,
    Triangle,
    gauss,
    gbell,
    shoulder_left,
    shoulder_right,
    trap,
    tri,
)
from .rulebase import LinguisticVariable, Rule, RuleBase

__all__ = [
    "Bell",
    "Gaussian",
    "LeftShoulder",
    "LinguisticVariable",
    "MamdaniSpec",
    "MamdaniSystem",
    "MembershipFunction",
    "RightShoulder",
    "Rule",
    "RuleBase",
    "Trapezoid",
    "Triangle",
    "eval_uniform_batch",
    "eval_uniform_grid",
    "eval_uniform_pair",
    "gauss",
    "gbell",
    "shoulder_left",
    "shoulder_right",
    "trap",
    "tri",
]
