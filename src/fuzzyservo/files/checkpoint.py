"""Tuning checkpoints: the population of an interrupted ``fuzzyservo tune``, to resume it.

An ``.npz`` file with the search state's arrays and a JSON header, read back with
``allow_pickle=False`` (data only). It holds everything a resume needs to give the
uninterrupted run's result bit for bit, and every setting of the run, so that a resume with
another setting is refused (:func:`fuzzyservo.analysis.autotune.tune_controller`).
"""

from __future__ import annotations

import io
import json
import os
import struct
import zipfile
import zlib
from pathlib import Path

import numpy as np

from .._io import atomic_write, npz_inflation, read_bytes
from ..analysis.autotune import Checkpoint, DoneStage
from ..analysis.tuning import SearchState
from ..errors import InputError

__all__ = ["checkpoint_path", "load_checkpoint", "save_checkpoint"]


#: Largest checkpoint read [bytes]: a tuning's population and history take kilobytes to a
#: few megabytes.
_MAX_CHECKPOINT_BYTES = 256 * 1024 * 1024


def checkpoint_path(out: Path) -> Path:
    """Where an interrupted tuning for the gains file ``out`` keeps its population."""
    return out.with_name(out.name + ".partial.npz")


#: Version of the checkpoint layout written (1: the population only, cannot resume exactly).
FORMAT = 2


def save_checkpoint(path: str | Path, ckpt: Checkpoint) -> Path:
    """Write ``ckpt`` as an ``.npz`` file: the search state's arrays (population in the
    search's own coordinates, costs, history of the best cost) and a JSON header (every
    setting, the parameters' digest, the version, the stage, the random generator's state
    and the completed stages)."""
    path = Path(path)
    st = ckpt.state
    header = json.dumps({
        "format": FORMAT, "setup": ckpt.setup, "params": ckpt.params,
        "version": ckpt.version, "stage": ckpt.stage, "restart": ckpt.restart,
        "generation": st.generation,
        "n_evaluations": st.n_evaluations, "rng_state": st.rng_state,
        "done": {k: {"gains": list(d.gains), "n_evaluations": d.n_evaluations,
                     "generations": d.generations, "converged": d.converged,
                     "cost": d.cost, "restart_spread": d.restart_spread}
                 for k, d in ckpt.done.items()}})
    with atomic_write(path, binary=True) as fh:
        np.savez(fh, population=np.asarray(st.population, dtype=np.float64),
                 costs=np.asarray(st.costs, dtype=np.float64),
                 history=np.asarray(st.history, dtype=np.float64), header=np.array(header))
    return path


def load_checkpoint(path: str | Path) -> Checkpoint:
    """Read a checkpoint written by :func:`save_checkpoint` (data only: ``allow_pickle=False``).

    Raises
    ------
    InputError
        The file is missing, or is not a complete checkpoint of this layout (truncated,
        another format, an older layout, a header without a field); the message names the
        file and says to delete it or to run without ``--resume``.
    """
    path = Path(path)
    if not os.path.lexists(path):
        raise InputError(f"cannot read checkpoint {str(path)!r}: No such file or directory; "
                         f"run without --resume")
    try:  # a regular file, one bounded read: never a FIFO's wait or /dev/zero's flood
        data = read_bytes(path, "checkpoint", limit=_MAX_CHECKPOINT_BYTES)
    except InputError as exc:
        raise InputError(f"{exc}; delete it or run without --resume") from None
    inflated = npz_inflation(data)
    if inflated is not None:
        raise InputError(f"checkpoint {str(path)!r} is unreadable, truncated or not a tuning "
                         f"checkpoint ({len(data)} bytes; {inflated}); delete it or run "
                         f"without --resume")
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as z:
            h = json.loads(str(z["header"]))
            if not isinstance(h, dict) or h.get("format") != FORMAT:
                layout = h.get("format", 1) if isinstance(h, dict) else "?"
                raise ValueError(f"checkpoint layout {layout!r} of an earlier version, this "
                                 f"version resumes layout {FORMAT} only")
            pop = np.asarray(z["population"], dtype=np.float64)
            costs = np.asarray(z["costs"], dtype=np.float64)
            history = np.asarray(z["history"], dtype=np.float64)
        rng_state = h["rng_state"]
        if not isinstance(rng_state, dict) or not isinstance(h["setup"], dict):
            raise TypeError("rng_state and setup must be tables")
        np.random.default_rng().bit_generator.state = rng_state  # a valid PCG64 state
        state = SearchState(generation=int(h["generation"]), population=np.atleast_2d(pop),
                            costs=costs.reshape(-1), rng_state=rng_state,
                            history=tuple(float(x) for x in history.reshape(-1)),
                            n_evaluations=int(h["n_evaluations"]))
        done = {str(k): DoneStage(gains=tuple(float(x) for x in v["gains"]),
                                  n_evaluations=int(v["n_evaluations"]),
                                  generations=int(v["generations"]),
                                  converged=bool(v["converged"]), cost=float(v["cost"]),
                                  restart_spread=float(v["restart_spread"]))
                for k, v in dict(h["done"]).items()}
        return Checkpoint(setup=dict(h["setup"]), params=str(h["params"]),
                          version=str(h["version"]), stage=str(h["stage"]), state=state,
                          done=done, restart=int(h["restart"]))
    except (OSError, EOFError, ValueError, KeyError, TypeError, AttributeError,
            zipfile.BadZipFile, zlib.error, struct.error) as exc:
        reason = " ".join(str(exc).split()) or type(exc).__name__
        if "pickle" in reason:  # numpy's text would advise loading it unsafely
            reason = "it holds pickled objects, which fuzzyservo never loads"
        raise InputError(f"checkpoint {str(path)!r} is unreadable, truncated or not a "
                         f"tuning checkpoint ({len(data)} bytes; {reason}); delete it or run "
                         f"without --resume") from None
