"""The parameter file of an identified axis: every field of the identified set, and the record
of how it was made (docs/identify.md, "The output file").

The file is a parameter file like any other (``--params AXIS.toml`` on every command): it
lists every field of every group, so it fully defines the set whatever ``--set`` it is
combined with. The table ``[identification]`` (:data:`fuzzyservo.plant.params.RECORD_TABLE`,
which the parameter readers skip) records the data file and its SHA-256 digest, the plant and
mode, the fitted fields with their starting values, estimates, standard errors, bounds and
bootstrap intervals, the residual RMS of each channel, the correlation matrix, the warnings
and the command that made the file. Numbers are written as Python's shortest round-trip
decimals, so reading the file gives the estimates bit for bit.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from .._io import write_text_atomic
from ..plant import to_dict
from ..plant.params import RECORD_TABLE
from .fit import Identification

__all__ = ["record_document", "render_axis_toml", "write_axis_toml"]

_HEAD = ("# The parameter set of an identified axis (SI units; every field, so the file defines "
         "the set\n# whatever --set it is combined with): fuzzyservo simulate --params THIS.toml "
         "...\n# [identification] records how it was made; parameter readers skip it.\n")


def _floats(values: Any) -> list[float]:
    return [float(v) for v in values]


def record_document(ident: Identification, *, data: str, digest: str, command: str,
                    base_set: str, version: str, extra: dict[str, Any] | None = None
                    ) -> dict[str, Any]:
    """The ``[identification]`` table of ``ident`` as a TOML-ready mapping."""
    rec: dict[str, Any] = {
        "version": version,
        "command": command,
        "data": data,
        "data_digest": digest,
        "plant": ident.plant,
        "mode": ident.mode,
        "base_set": base_set,
        "start_position": float(ident.position),
        "samples": int(ident.t.size),
        "samples_used": int(ident.used.sum()),
        "sample_time": float(ident.t[1] - ident.t[0]) if ident.t.size > 1 else 0.0,
        "channels": list(ident.channels),
        "fitted": list(ident.names),
        "units": list(ident.units),
        "initial": _floats(ident.initial),
        "estimate": _floats(ident.estimate),
        "std_error": _floats(ident.std_error),
        "lower_bound": _floats(ident.bounds[:, 0]),
        "upper_bound": _floats(ident.bounds[:, 1]),
        "residual_rms": {c: float(v) for c, v in ident.residual_rms.items()},
        "sigma": {c: float(v) for c, v in ident.sigma.items()},
        "chi2": float(ident.chi2),
        "correlation": [_floats(row) for row in ident.correlation],
        "starts": len(ident.start_costs),
        "runs": int(ident.n_runs),
        "warnings": list(ident.warnings),
        "notes": list(ident.notes),
    }
    if ident.interval is not None and ident.bootstrap is not None:
        rec["bootstrap"] = int(ident.bootstrap.shape[0])
        rec["interval_level"] = float(ident.level)
        rec["interval_low"] = _floats(ident.interval[:, 0])
        rec["interval_high"] = _floats(ident.interval[:, 1])
    if extra:
        rec.update(extra)
    return rec


def render_axis_toml(ident: Identification, *, data: str, digest: str, command: str,
                     base_set: str, version: str, extra: dict[str, Any] | None = None) -> str:
    """The text of the parameter file: every field of ``ident.params``, then the record."""
    import tomli_w

    doc: dict[str, Any] = dict(to_dict(ident.params))
    doc[RECORD_TABLE] = record_document(ident, data=data, digest=digest, command=command,
                                        base_set=base_set, version=version, extra=extra)
    return _HEAD + tomli_w.dumps(doc)


def write_axis_toml(path: str | Path, text: str) -> Path:
    """Write the parameter file atomically (a failure leaves an existing file as it was)."""
    return write_text_atomic(path, text)
