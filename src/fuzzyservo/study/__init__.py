"""fuzzyservo.study: the paper's study (Figs. 4-8, claims C1-C8, report), computed then written."""

from __future__ import annotations

from .claims import CLAIM_TEXTS, Claim, evaluate_claims
from .paper_study import PlantStudy, StudyConfig, run_plant_study

__all__ = [
    "CLAIM_TEXTS",
    "Claim",
    "PlantStudy",
    "StudyConfig",
    "evaluate_claims",
    "run_plant_study",
]
