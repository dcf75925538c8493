"""Self-tuning fuzzy PI controller (paper eqs. 9-12, Fig. 2; Mudi & Pal, IEEE TFS 7(1), 1999).

Identical to :class:`~fuzzyservo.control.fuzzy_pi.FuzzyPIController` except that the output
scaling is multiplied every sample by the gain-updating factor α_F from the Fig. 3b rule base,
evaluated on the same normalised inputs (e_n, Δe_n)::

    Δu(k) = (α_F(k) K_Δu) Δu_n(k)                  (eq. 11)

With the paper's α system and exact centroid defuzzification α_F lies in [1/18, 17/18]; it has
no memory of its own. The maths is :func:`~fuzzyservo.control.fuzzy_pi.fuzzy_pi_step` with the
self-tuning flag set.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..errors import ParameterError
from .fuzzy_pi import FuzzyPIController

__all__ = ["SelfTuningFuzzyPIController"]


@dataclass(frozen=True, slots=True, kw_only=True, eq=False)
class SelfTuningFuzzyPIController(FuzzyPIController):
    """Self-tuning fuzzy PI; fields as :class:`FuzzyPIController`, and ``alpha_rules`` /
    ``alpha_lims`` (the Fig. 3b system, e.g. from ``fuzzyservo.paper.alpha_system()``) are
    required."""

    self_tuning: ClassVar[bool] = True

    def __post_init__(self) -> None:
        FuzzyPIController.__post_init__(self)
        if self.alpha_rules.shape[0] != 1 and np.all(self.alpha_rules < 0):
            raise ParameterError(
                "the self-tuning fuzzy PI needs the alpha rule base (alpha_rules/alpha_lims, "
                "e.g. from fuzzyservo.paper.alpha_system()); got none")
