"""Tuning checkpoints on disk: round trip, data only, a clear error for a file that is not one."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fuzzyservo.analysis.autotune import Checkpoint
from fuzzyservo.errors import InputError
from fuzzyservo.files import checkpoint_path, load_checkpoint, save_checkpoint


def test_checkpoint_round_trip(tmp_path: Path) -> None:
    pop = np.random.default_rng(3).uniform(0.1, 10.0, size=(9, 3))
    ck = Checkpoint(controller="stfpi", plant="nonlinear", objective="itae", seed=4,
                    stage="refine", generation=7, population=pop,
                    done={"fpi": (10.0, 5e3, 2e-3), "rise": (10.0, 5e3, 4e-3)})
    path = save_checkpoint(checkpoint_path(tmp_path / "g.toml"), ck)
    assert path.name == "g.toml.partial.npz"
    back = load_checkpoint(path)
    assert np.array_equal(back.population, pop)  # float64 stored exactly
    assert (back.controller, back.plant, back.objective, back.seed, back.stage,
            back.generation, back.done) == ("stfpi", "nonlinear", "itae", 4, "refine", 7,
                                            ck.done)


def test_not_a_checkpoint(tmp_path: Path) -> None:
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    with pytest.raises(InputError, match="junk"):
        load_checkpoint(tmp_path / "junk.npz")
    with pytest.raises(InputError, match="cannot read checkpoint"):
        load_checkpoint(tmp_path / "none.npz")
