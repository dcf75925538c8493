"""The paper's two fuzzy systems (Aly et al. 2012, Fig. 3; identical to Mudi & Pal 1999).

Both tables are transcribed once, as printed: rows Δe, columns e, both ordered NB .. PB.
The inputs e and Δe, and the output Δu, have seven uniform triangles on [-1, 1]; the gain
updating factor α has seven uniform triangles ZO, VS, S, SB, MB, B, VB on [0, 1] peaking at
k/6. Inference is Mamdani min AND, min implication, max aggregation, centroid over the output
universe ("MOR" and "COA" in the paper).
"""

from __future__ import annotations

from pathlib import Path

from ..errors import ParameterError
from ..fuzzy import FuzzySystem, Variable

__all__ = [
    "ALPHA_LABELS",
    "ALPHA_TABLE",
    "DU_TABLE",
    "LABELS",
    "SYSTEM_FILES",
    "alpha_system",
    "du_system",
    "paper_fuzzy_system",
    "system_file",
    "write_system_files",
]

#: Labels of e, Δe and Δu, from negative big to positive big.
LABELS: tuple[str, ...] = ("NB", "NM", "NS", "ZO", "PS", "PM", "PB")
#: Labels of α, from zero to very big.
ALPHA_LABELS: tuple[str, ...] = ("ZO", "VS", "S", "SB", "MB", "B", "VB")

#: Fig. 3a, rule table for Δu: DU_TABLE[row Δe][column e].
DU_TABLE: tuple[tuple[str, ...], ...] = (
    ("NB", "NB", "NB", "NM", "NS", "NS", "ZO"),  # Δe = NB
    ("NB", "NM", "NM", "NM", "NS", "ZO", "PS"),  # Δe = NM
    ("NB", "NM", "NS", "NS", "ZO", "PS", "PM"),  # Δe = NS
    ("NB", "NM", "NS", "ZO", "PS", "PM", "PB"),  # Δe = ZO
    ("NM", "NS", "ZO", "PS", "PS", "PM", "PB"),  # Δe = PS
    ("NS", "ZO", "PS", "PM", "PM", "PM", "PB"),  # Δe = PM
    ("ZO", "PS", "PS", "PM", "PB", "PB", "PB"),  # Δe = PB
)

#: Fig. 3b, rule table for α: ALPHA_TABLE[row Δe][column e].
ALPHA_TABLE: tuple[tuple[str, ...], ...] = (
    ("VB", "VB", "VB", "B", "SB", "S", "ZO"),  # Δe = NB
    ("VB", "VB", "B", "B", "MB", "S", "VS"),  # Δe = NM
    ("VB", "MB", "B", "VB", "VS", "S", "VS"),  # Δe = NS
    ("S", "SB", "MB", "ZO", "MB", "SB", "S"),  # Δe = ZO
    ("VS", "S", "VS", "VB", "B", "MB", "VB"),  # Δe = PS
    ("VS", "S", "MB", "B", "B", "VB", "VB"),  # Δe = PM
    ("ZO", "S", "SB", "B", "VB", "VB", "VB"),  # Δe = PB
)


def _inputs() -> tuple[Variable, Variable]:
    e = Variable.uniform("e", (-1.0, 1.0), LABELS)
    de = Variable.uniform("de", (-1.0, 1.0), LABELS)
    return e, de


def du_system() -> FuzzySystem:
    """The fuzzy PI's Δu system of Fig. 3a (normalised e, Δe -> Δu_n, all on [-1, 1]).

    It has no value for when no rule fires (default NaN): its complete table over inputs whose
    triangles cover [-1, 1] always fires. The shipped files hold :func:`paper_fuzzy_system`.

    Examples
    --------
    >>> from fuzzyservo.fuzzy import evaluate
    >>> round(float(evaluate(du_system(), [1.0, 1.0])[0]), 12)  # centroid of a half triangle
    0.888888888889
    """
    e, de = _inputs()
    du = Variable.uniform("du", (-1.0, 1.0), LABELS)
    return FuzzySystem.from_table(DU_TABLE, columns=e, rows=de, output=du, name="paper_du")


def alpha_system() -> FuzzySystem:
    """The self-tuning gain-updating factor α of Fig. 3b (e, Δe on [-1, 1] -> α on [0, 1]).

    Examples
    --------
    >>> round(float(evaluate(alpha_system(), [0.0, 0.0])[0]), 12)   # 1/18
    0.055555555556
    """
    e, de = _inputs()
    alpha = Variable.uniform("alpha", (0.0, 1.0), ALPHA_LABELS)
    return FuzzySystem.from_table(ALPHA_TABLE, columns=e, rows=de, output=alpha,
                                  name="paper_alpha")


#: File names of the paper's systems shipped in ``fuzzyservo/data/systems`` (one per format).
SYSTEM_FILES: tuple[str, ...] = tuple(f"paper-{role}.{ext}" for role in ("du", "alpha")
                                      for ext in ("fis", "fcl", "fll"))


def paper_fuzzy_system(role: str) -> FuzzySystem:
    """The paper's ``"du"`` or ``"alpha"`` system as the shipped files hold it.

    The output's default (the value when no rule fires) is the middle of its range, MATLAB's
    convention, so that one system is written unchanged to .fis, FCL and FLL; it is never used:
    the complete rule table over inputs whose triangles cover [-1, 1] always fires.
    """
    import dataclasses

    makers = {"du": du_system, "alpha": alpha_system}
    if role not in makers:
        raise ParameterError(f"role must be 'du' or 'alpha', got {role!r}")
    s = makers[role]()
    out = s.outputs[0]
    mid = 0.5 * (out.range[0] + out.range[1])
    return dataclasses.replace(s, outputs=(dataclasses.replace(out, default=mid),))


def write_system_files(folder: str | Path) -> list[Path]:
    """Write the paper's two systems in every format into ``folder`` (the package data is made
    this way: ``python -c "from fuzzyservo.paper.rulebases import write_system_files;
    write_system_files('src/fuzzyservo/data/systems')"``)."""
    from ..formats import write_system

    out = []
    for name in SYSTEM_FILES:
        role = name.split("-")[1].split(".")[0]
        path = Path(folder) / name
        write_system(paper_fuzzy_system(role), path)
        out.append(path)
    return out


def system_file(role: str, fmt: str = "fll") -> Path:
    """Path of a shipped file of the paper's ``role`` system in format ``fmt``."""
    from importlib import resources

    name = f"paper-{role}.{fmt}"
    if name not in SYSTEM_FILES:
        raise ParameterError(f"no shipped system {name!r}; shipped: {', '.join(SYSTEM_FILES)}")
    return Path(str(resources.files("fuzzyservo") / "data" / "systems" / name))
