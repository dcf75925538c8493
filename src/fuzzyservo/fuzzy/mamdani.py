"""Mamdani systems: a declared spec, compiled once, evaluated on scalars or numpy arrays."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal, get_args, overload

import numpy as np

from .._typing import ArrayLike, FloatArray, IntArray
from ..errors import EmptyFuzzySetError, InputError, ParameterError
from . import defuzz
from .kernels import LIMS_SIZE, eval_uniform_batch, eval_uniform_checked
from .rulebase import LinguisticVariable, RuleBase

__all__ = [
    "Aggregation",
    "AndOperator",
    "Defuzzifier",
    "Implication",
    "MamdaniSpec",
    "MamdaniSystem",
]

AndOperator = Literal["min", "product"]
Implication = Literal["min", "product"]
Aggregation = Literal["max", "bounded_sum"]
Defuzzifier = Literal["exact_centroid", "sampled_centroid", "bisector", "mean_of_maxima"]


def _check_choice(field_name: str, value: object, allowed: object) -> None:
    options = get_args(allowed)
    if value not in options:
        raise ParameterError(
            f"{field_name} must be one of {', '.join(map(repr, options))}, got {value!r}"
        )


@dataclass(frozen=True, slots=True, kw_only=True)
class MamdaniSpec:
    """Every choice a Mamdani system makes, named (the paper's: min, min, max, centroid).

    Parameters
    ----------
    and_op : {"min", "product"}
        AND of the antecedent clauses.
    implication : {"min", "product"}
        Clipping (min) or scaling (product) of the consequent set by the rule strength.
    aggregation : {"max", "bounded_sum"}
        Combination of the implied sets: max, or min(1, sum).
    defuzz : {"exact_centroid", "sampled_centroid", "bisector", "mean_of_maxima"}
        Exact centroid (analytic for piecewise-linear outputs, adaptive quadrature otherwise),
        centroid by the trapezoid rule on ``samples`` points, bisector of area, or mean of the
        maxima. Every defuzzifier works on the output universe only.
    samples : int
        Points of the output universe for ``sampled_centroid`` (and for bisector / mean of
        maxima with Gaussian or bell outputs), >= 2.
    default : float or None
        Output when no rule fires (the aggregate is empty); None raises
        ``EmptyFuzzySetError`` instead.
    quad_tol : float
        Absolute and relative tolerance of ``scipy.integrate.quad`` for Gaussian or bell
        outputs, > 0 [1].
    """

    and_op: AndOperator = "min"  #: AND of antecedent clauses
    implication: Implication = "min"  #: implication operator
    aggregation: Aggregation = "max"  #: aggregation operator
    defuzz: Defuzzifier = "exact_centroid"  #: defuzzification method
    samples: int = 1001  #: output samples for the sampled methods [1]
    default: float | None = None  #: output when no rule fires [unit of the output]
    quad_tol: float = 1e-10  #: quadrature tolerance for smooth outputs [1]

    def __post_init__(self) -> None:
        _check_choice("and_op", self.and_op, AndOperator)
        _check_choice("implication", self.implication, Implication)
        _check_choice("aggregation", self.aggregation, Aggregation)
        _check_choice("defuzz", self.defuzz, Defuzzifier)
        if isinstance(self.samples, bool) or not isinstance(self.samples, int) or self.samples < 2:
            raise ParameterError(f"samples must be an integer >= 2, got {self.samples!r}")
        if self.default is not None and not math.isfinite(self.default):
            raise ParameterError(f"default must be finite or None, got {self.default!r}")
        if not (self.quad_tol > 0.0 and math.isfinite(self.quad_tol)):
            raise ParameterError(f"quad_tol must be finite and > 0, got {self.quad_tol!r}")


@dataclass(frozen=True, slots=True)
class _Compiled:
    """Arrays the evaluation needs, built once per system."""

    rule_inputs: IntArray  # (R, n_in) term index, -1 = not mentioned
    rule_out: IntArray  # (R,)
    uniform: tuple[IntArray, FloatArray] | None  # (rules, lims) for the fast kernel


@dataclass(frozen=True, slots=True, kw_only=True)
class MamdaniSystem:
    """A two-input Mamdani fuzzy system.

    Parameters
    ----------
    rules : RuleBase
        Rule base over two input variables and one output variable.
    spec : MamdaniSpec
        The operators and the defuzzifier.

    Examples
    --------
    >>> from fuzzyservo.paper import du_system
    >>> round(float(du_system().evaluate(1.0, 1.0)), 12)
    0.888888888889
    """

    rules: RuleBase  #: the rule base (inputs, output, rules)
    spec: MamdaniSpec = field(default_factory=MamdaniSpec)  #: operators and defuzzifier
    _c: _Compiled = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if len(self.rules.inputs) != 2:
            raise ParameterError(
                f"a MamdaniSystem takes 2 inputs (e, de), got {len(self.rules.inputs)}"
            )
        rule_inputs = np.array([r.antecedent for r in self.rules.rules], dtype=np.int64)
        rule_out = np.array([r.consequent for r in self.rules.rules], dtype=np.int64)
        object.__setattr__(self, "_c", _Compiled(rule_inputs, rule_out, self._uniform_args()))
        defuzz.check_output(self.rules.output)

    @property
    def inputs(self) -> tuple[LinguisticVariable, ...]:
        """The input variables (e, de)."""
        return self.rules.inputs

    @property
    def output(self) -> LinguisticVariable:
        """The output variable."""
        return self.rules.output

    def _uniform_args(self) -> tuple[IntArray, FloatArray] | None:
        s = self.spec
        if (s.and_op, s.implication, s.aggregation, s.defuzz) != ("min", "min", "max",
                                                                  "exact_centroid"):
            return None
        v1, v2 = self.rules.inputs
        out = self.rules.output
        if not (v1.is_uniform_triangles() and v2.is_uniform_triangles()
                and out.is_uniform_triangles()):
            return None
        try:
            table = self.rules.as_table()
        except ParameterError:
            return None
        lims = np.empty(LIMS_SIZE, dtype=np.float64)
        lims[0:2] = v1.universe
        lims[2:4] = v2.universe
        lims[4:6] = out.universe
        lims[6] = len(out.terms)
        lims[7] = np.nan if s.default is None else s.default
        return table, lims

    def kernel_args(self) -> tuple[IntArray, FloatArray]:
        """``(rules, lims)`` for the controllers' compiled loops: the uniform-grid tables when
        the system has that form (:meth:`uniform_kernel_args`), else the system packed for the
        general evaluator (:func:`fuzzyservo.fuzzy.general.compile_system`)."""
        if self._c.uniform is not None:
            return self.uniform_kernel_args()
        from .loop import loop_system
        from .system import from_mamdani

        return loop_system(from_mamdani(self), source="MamdaniSystem").kernel_args()

    def uniform_kernel_args(self) -> tuple[IntArray, FloatArray]:
        """``(rules, lims)`` for :func:`fuzzyservo.fuzzy.kernels.eval_uniform_grid`.

        Returns
        -------
        rules : int64 ndarray (n2, n1)
            Output label index per (Δe row, e column), -1 = no rule.
        lims : float64 ndarray (8,)
            lo1, hi1, lo2, hi2, out lo, out hi, n_out, default (NaN when the spec has none).

        Raises
        ------
        ParameterError
            If the system is not two-input min/min/max/exact-centroid on uniform triangles
            with a table-shaped rule base.
        """
        if self._c.uniform is None:
            raise ParameterError(
                "uniform_kernel_args needs min AND, min implication, max aggregation, exact "
                "centroid, uniform triangle partitions and one rule per table cell"
            )
        rules, lims = self._c.uniform
        return rules.copy(), lims.copy()

    def _empty(self, e: float, de: float) -> EmptyFuzzySetError:
        return EmptyFuzzySetError(
            f"no rule fires at (e={e!r}, de={de!r}) and the spec declares no default output"
        )

    def evaluate_scalar(self, e: float, de: float) -> float:
        """Crisp output at one point: the cheap path a controller calls once per sample.

        Parameters
        ----------
        e, de : float
            The two inputs [units of the input universes]; clipped to the universes.

        Returns
        -------
        float
            The crisp output [unit of the output universe].

        Raises
        ------
        InputError
            If an input is NaN or infinite.
        EmptyFuzzySetError
            If no rule fires and the spec has no default.
        """
        u = self._c.uniform
        if u is not None:
            v: float = eval_uniform_checked(e, de, u[0], u[1])
            if v != v:
                if not (math.isfinite(e) and math.isfinite(de)):
                    raise InputError(f"inputs must be finite, got e={e!r}, de={de!r}")
                raise self._empty(e, de)
            return v
        return float(self.evaluate(np.float64(e), np.float64(de)))

    @overload
    def evaluate(self, e: float, de: float) -> float: ...

    @overload
    def evaluate(self, e: ArrayLike, de: ArrayLike) -> FloatArray: ...

    def evaluate(self, e: ArrayLike, de: ArrayLike) -> FloatArray | float:
        """Crisp output for broadcast arrays of inputs (float64 out; a float for float in).

        Parameters
        ----------
        e, de : array_like
            Inputs, broadcast together [units of the input universes]; clipped to the
            universes.

        Returns
        -------
        ndarray of float64 or float
            Crisp outputs, shape of the broadcast inputs [unit of the output universe].

        Raises
        ------
        InputError
            If an input is NaN or infinite, or not numeric.
        EmptyFuzzySetError
            If no rule fires at some point and the spec has no default.
        """
        if type(e) is float and type(de) is float:
            return self.evaluate_scalar(e, de)
        try:
            x1, x2 = np.broadcast_arrays(
                np.asarray(e, dtype=np.float64), np.asarray(de, dtype=np.float64)
            )
        except (TypeError, ValueError) as exc:
            raise InputError(f"inputs must be numeric arrays that broadcast: {exc}") from None
        shape = x1.shape
        a = np.ascontiguousarray(x1.ravel())
        b = np.ascontiguousarray(x2.ravel())
        out = np.empty(a.shape[0], dtype=np.float64)
        u = self._c.uniform
        if u is not None:
            # the kernel flags the first NaN result: a non-finite input or an empty set
            if eval_uniform_batch(a, b, u[0], u[1], out) >= 0:
                self._raise_first_bad(a, b, out)
            return out.reshape(shape)
        self._raise_first_bad(a, b, None)
        defuzz.evaluate_general(self, a, b, out)
        if np.isnan(out).any():
            self._raise_first_bad(a, b, out)
        return out.reshape(shape)

    def _raise_first_bad(self, a: FloatArray, b: FloatArray, out: FloatArray | None) -> None:
        """Raise for the first non-finite input, else for the first empty output (NaN)."""
        bad = ~(np.isfinite(a) & np.isfinite(b))
        if bad.any():
            k = int(np.flatnonzero(bad)[0])
            raise InputError(
                f"inputs must be finite, got e={a[k]!r}, de={b[k]!r} at flat index {k}"
            )
        if out is not None:
            k = int(np.flatnonzero(np.isnan(out))[0])
            raise self._empty(float(a[k]), float(b[k]))

    def rule_strengths(self, e: FloatArray, de: FloatArray) -> FloatArray:
        """Firing strength of every rule, shape (n_points, n_rules), inputs already clipped.

        Parameters
        ----------
        e, de : ndarray of float64, shape (n,)
            Finite inputs inside the universes.
        """
        mus = []
        for var, x in zip(self.rules.inputs, (e, de), strict=True):
            mus.append(np.stack([mf(x) for _, mf in var.terms], axis=-1))  # (n, n_terms)
        ri = self._c.rule_inputs
        w = np.ones((e.shape[0], ri.shape[0]))
        for k in range(2):
            cols = ri[:, k]
            m = np.where(cols >= 0, mus[k][:, np.maximum(cols, 0)], 1.0)
            w = np.minimum(w, m) if self.spec.and_op == "min" else w * m
        return w

    @property
    def rule_outputs(self) -> IntArray:
        """Output term index of every rule, shape (n_rules,)."""
        return self._c.rule_out.copy()
