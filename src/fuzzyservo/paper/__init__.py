"""fuzzyservo.paper: the paper's data (rule bases of Fig. 3; parameter sets)."""

from __future__ import annotations

from .published import (
    PAPER_PIDS,
    PHYSICAL_CHOICES,
    SET_NAMES,
    TABLE_A1,
    PaperPID,
    named_set,
    paper_params,
    stiff_oil_params,
)
from .rulebases import (
    SYSTEM_FILES,
    alpha_system,
    du_system,
    paper_fuzzy_system,
    system_file,
    write_system_files,
)

__all__ = [
    "PAPER_PIDS",
    "PHYSICAL_CHOICES",
    "SET_NAMES",
    "SYSTEM_FILES",
    "TABLE_A1",
    "PaperPID",
    "alpha_system",
    "du_system",
    "named_set",
    "paper_fuzzy_system",
    "paper_params",
    "stiff_oil_params",
    "system_file",
    "write_system_files",
]
