"""Fuzzy PI with self-tuning scaling factors that are functions of the error (after Woo, Chung
and Lin 2000), a second published self-tuning scheme beside the paper's (Mudi & Pal 1999).

Source: Z.-W. Woo, H.-Y. Chung, J.-J. Lin, "A PID type fuzzy controller with self-tuning
scaling factors", Fuzzy Sets and Systems 115(2), 321-326, 2000. Their PID-type fuzzy
controller is a fuzzy PD map F(K_e e, K_d Δe) whose output feeds a proportional path (factor
α) and an integrating path (factor β); on line, two functions of the error rescale the
error-change input factor and the integral output factor, so the loop is aggressive far from
the setpoint and gentle near it::

    φ(e) = a |e| + b         (grows with |e|: the factor of the error-change input)
    ψ(e) = c (1 - |e|) + d   (grows as e -> 0: the factor of the integral output)

Here the same two functions act on the paper's incremental fuzzy PI, which *is* the
integrating path of Woo et al.'s controller (their α = 0): per sample k, with everything as in
:mod:`fuzzyservo.control.fuzzy_pi` (filter, e(-1) convention, Δe per sample or per second)::

    e_n = K_e e,   m = min(|e_n|, 1)               (the normalised error, clipped)
    Δe_n = φ(m) K_Δe Δe,   φ(m) = a m + b           (e_n and Δe_n clipped to [-1, 1])
    Δu(k) = ψ(m) K_Δu Δu_n(e_n, Δe_n),   ψ(m) = c (1 - m) + d
    u(k) = sat(u(k-1) + Δu(k))                      (saturated before it is stored)

Δu_n is the paper's Fig. 3a rule base (the ``du`` system), evaluated exactly as for the other
fuzzy PIs. Δu_n grows with e_n and Δe_n alike: Δu_n ≈ k (e_n + Δe_n) with k between about 1/2
(on the diagonal) and 1 (on the axes), so the loop acts as a PI whose proportional gain is
≈ k ψ φ K_Δu K_Δe and integral gain ≈ k ψ K_Δu K_e / h (h the sample time): φ raises the
proportional action at large errors, ψ the integral action near the setpoint, as in Woo et
al., where the proportional gain of the integrating path is β K_d and its integral gain β K_e.

Discretisation: the velocity form of the fuzzy PI (a sum of increments); φ and ψ are
memoryless and use the error of the same sample. Anti-windup: the command is saturated before
it is stored (the velocity form needs no other). The run's α trace records ψ.

The law is the fuzzy PI's (``fuzzy_pi_step`` and ``fuzzy_pi.c``, one C port) with the α source
code 2; a = c = 0, b = d = 1 gives the plain fuzzy PI exactly. Departures from Woo et al. are
listed in :data:`fuzzyservo.paper.departures.WOO_DEPARTURES` and docs/model.md ("Baselines
beside the paper's controllers").
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from .._typing import FloatArray, IntArray
from ..errors import ParameterError
from .fuzzy_pi import (
    ALPHA_WOO,
    WOO_FPI_GENERAL_LAW,
    WOO_FPI_LAW,
    WOO_GAIN_NAMES,
    FuzzyPIController,
)
from .law import Law

__all__ = ["WooFuzzyPIController"]


@dataclass(frozen=True, slots=True, kw_only=True, eq=False)
class WooFuzzyPIController(FuzzyPIController):
    """Fuzzy PI whose error-change and output scalings are multiplied every sample by
    φ(|e_n|) = a |e_n| + b and ψ(|e_n|) = c (1 - |e_n|) + d (Woo, Chung & Lin 2000).

    Fields as :class:`~fuzzyservo.control.fuzzy_pi.FuzzyPIController` (the ``du`` system only;
    no α rule base), and:

    Parameters
    ----------
    phi_a, phi_b : float
        Slope a and offset b of φ [-], >= 0 (φ(0) = b, φ(1) = a + b).
    psi_c, psi_d : float
        Slope c and offset d of ψ [-], >= 0 (ψ(1) = d, ψ(0) = c + d).
    """

    phi_a: float = 0.0  #: slope a of φ [-]
    phi_b: float = 1.0  #: offset b of φ [-]
    psi_c: float = 0.0  #: slope c of ψ [-]
    psi_d: float = 1.0  #: offset d of ψ [-]

    gain_names: ClassVar[tuple[str, ...]] = WOO_GAIN_NAMES
    self_tuning: ClassVar[bool] = True

    def __post_init__(self) -> None:
        FuzzyPIController.__post_init__(self)
        for name in WOO_GAIN_NAMES[3:]:
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ParameterError(f"gain {name} must be finite and >= 0, got {value!r}")

    @property
    def law(self) -> Law:  # type: ignore[override]
        """:data:`~fuzzyservo.control.fuzzy_pi.WOO_FPI_LAW` for a Δu system on a uniform grid,
        :data:`~fuzzyservo.control.fuzzy_pi.WOO_FPI_GENERAL_LAW` for a general one."""
        return WOO_FPI_GENERAL_LAW if self.du_rules.shape[0] == 1 else WOO_FPI_LAW

    def law_constants(self) -> FloatArray:
        """As the fuzzy PI's, with the α source 2 (Woo et al.'s functions)."""
        k = FuzzyPIController.law_constants(self)
        k[5] = ALPHA_WOO
        return np.asarray(k)

    def systems(self) -> dict[str, tuple[IntArray, FloatArray]]:
        """The one fuzzy system the law evaluates: ``du``."""
        return {"du": (self.du_rules, self.du_lims)}
