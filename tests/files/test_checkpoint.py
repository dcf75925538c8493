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


@pytest.mark.parametrize("keep", [0, 22, 800, -1])
def test_truncated_checkpoint_is_one_line_naming_the_way_out(tmp_path: Path, keep: int) -> None:
    """Issue 9, row 11: a checkpoint cut anywhere (here to 0, 22, 800 bytes and one byte
    short) is an InputError naming the file and saying to delete it or run without
    --resume, never a BadZipFile or EOFError."""
    pop = np.random.default_rng(0).random((30, 3))
    path = save_checkpoint(tmp_path / "g.toml.partial.npz", Checkpoint(
        controller="pid", plant="linear", objective="itae", seed=0, stage="search",
        generation=3, population=pop))
    data = path.read_bytes()
    path.write_bytes(data[:keep])
    with pytest.raises(InputError, match="delete it or run without --resume") as info:
        load_checkpoint(path)
    assert "g.toml.partial.npz" in str(info.value) and "\n" not in str(info.value)


def test_a_checkpoint_that_would_inflate_or_holds_objects_is_refused(tmp_path: Path) -> None:
    """np.savez stores members uncompressed; a compressed member is a crafted file that could
    unpack into gigabytes, and an object array would need pickle."""
    bomb = tmp_path / "bomb.npz"
    with bomb.open("wb") as fh:
        np.savez_compressed(fh, population=np.zeros((2500, 3000)), header=np.array("{}"))
    with pytest.raises(InputError, match="compressed members"):
        load_checkpoint(bomb)
    objects = tmp_path / "objects.npz"
    with objects.open("wb") as fh:
        np.savez(fh, population=np.array([object()], dtype=object), header=np.array("{}"))
    with pytest.raises(InputError) as err:
        load_checkpoint(objects)
    assert "pickled objects, which fuzzyservo never loads" in str(err.value)
    assert "allow_pickle" not in str(err.value)
