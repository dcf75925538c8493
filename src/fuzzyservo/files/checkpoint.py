"""Tuning checkpoints: the population of an interrupted ``fuzzyservo tune``, to resume it.

An ``.npz`` file with the population array and a JSON header, read back with
``allow_pickle=False`` (data only).
"""

from __future__ import annotations

import io
import json
import struct
import zipfile
import zlib
from pathlib import Path

import numpy as np

from .._io import atomic_write, npz_inflation
from ..analysis.autotune import Checkpoint
from ..errors import InputError

__all__ = ["checkpoint_path", "load_checkpoint", "save_checkpoint"]


def checkpoint_path(out: Path) -> Path:
    """Where an interrupted tuning for the gains file ``out`` keeps its population."""
    return out.with_name(out.name + ".partial.npz")


def save_checkpoint(path: str | Path, ckpt: Checkpoint) -> Path:
    """Write ``ckpt`` as an ``.npz`` file (population array plus a JSON header)."""
    path = Path(path)
    header = json.dumps({"controller": ckpt.controller, "plant": ckpt.plant,
                         "objective": ckpt.objective, "seed": ckpt.seed, "stage": ckpt.stage,
                         "generation": ckpt.generation,
                         "done": {k: list(v) for k, v in ckpt.done.items()}})
    with atomic_write(path, binary=True) as fh:
        np.savez(fh, population=np.asarray(ckpt.population, dtype=np.float64),
                 header=np.array(header))
    return path


def load_checkpoint(path: str | Path) -> Checkpoint:
    """Read a checkpoint written by :func:`save_checkpoint` (data only: ``allow_pickle=False``).

    Raises
    ------
    InputError
        The file is missing, or is not a complete checkpoint (truncated, another format, a
        header without a field); the message names the file and says to delete it or to run
        without ``--resume``.
    """
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        missing = isinstance(exc, FileNotFoundError)
        raise InputError(f"cannot read checkpoint {str(path)!r}: {exc.strerror or exc}; "
                         f"{'' if missing else 'delete it or '}run without --resume") from None
    inflated = npz_inflation(data)
    if inflated is not None:
        raise InputError(f"checkpoint {str(path)!r} is unreadable, truncated or not a tuning "
                         f"checkpoint ({len(data)} bytes; {inflated}); delete it or run "
                         f"without --resume")
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as z:
            pop = np.asarray(z["population"], dtype=np.float64)
            h = json.loads(str(z["header"]))
        return Checkpoint(controller=str(h["controller"]), plant=str(h["plant"]),
                          objective=str(h["objective"]), seed=int(h["seed"]),
                          stage=str(h["stage"]), generation=int(h["generation"]),
                          population=np.atleast_2d(pop),
                          done={str(k): tuple(float(x) for x in v)
                                for k, v in dict(h["done"]).items()})
    except (OSError, EOFError, ValueError, KeyError, TypeError, AttributeError,
            zipfile.BadZipFile, zlib.error, struct.error) as exc:
        reason = " ".join(str(exc).split()) or type(exc).__name__
        if "pickle" in reason:  # numpy's text would advise loading it unsafely
            reason = "it holds pickled objects, which fuzzyservo never loads"
        raise InputError(f"checkpoint {str(path)!r} is unreadable, truncated or not a "
                         f"tuning checkpoint ({len(data)} bytes; {reason}); delete it or run "
                         f"without --resume") from None
