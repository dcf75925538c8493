"""Tuning checkpoints on disk: round trip, data only, a clear error for a file that is not one."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fuzzyservo.analysis.autotune import Checkpoint, DoneStage, TuningSetup, setup_record
from fuzzyservo.analysis.tuning import SearchState
from fuzzyservo.errors import InputError
from fuzzyservo.files import checkpoint_path, load_checkpoint, save_checkpoint


def _state(rows: int, generation: int, seed: int = 3) -> SearchState:
    rng = np.random.default_rng(seed)
    pop = rng.random((rows, 3))
    rng.random(17)  # a generator part-way through
    return SearchState(generation=generation, population=pop, costs=rng.random(rows) * 1e6,
                       rng_state=dict(rng.bit_generator.state),
                       history=tuple(float(x) for x in np.sort(rng.random(generation + 1))),
                       n_evaluations=rows * (generation + 1))


def _checkpoint(state: SearchState, **done: DoneStage) -> Checkpoint:
    setup = setup_record(TuningSetup(controller="stfpi", plant="nonlinear", seed=4,
                                     overrides=(("load.mass", 12345.5),)))
    return Checkpoint(setup=setup, params="ab" * 32, version="9.9", stage="refine",
                      state=state, done=done, restart=2)


def test_checkpoint_round_trip(tmp_path: Path) -> None:
    st = _state(9, 7)
    ck = _checkpoint(st, fpi=DoneStage(gains=(10.0, 5e3, 2e-3), n_evaluations=300,
                                       generations=40, converged=True, cost=0.1 / 3,
                                       restart_spread=0.25),
                     rise=DoneStage(gains=(10.0, 5e3, 1 / 3), n_evaluations=31),
                     **{"refine#0": DoneStage(gains=(1.0, 2.0, 3.0), n_evaluations=9,
                                              generations=2, converged=False, cost=7.0)})
    path = save_checkpoint(checkpoint_path(tmp_path / "g.toml"), ck)
    assert path.name == "g.toml.partial.npz"
    back = load_checkpoint(path)
    # float64 arrays, the 128-bit generator state and the setup stored exactly
    assert np.array_equal(back.state.population, st.population)
    assert np.array_equal(back.state.costs, st.costs)
    assert back.state.history == st.history and back.state.rng_state == st.rng_state
    a, b = np.random.default_rng(), np.random.default_rng()
    a.bit_generator.state, b.bit_generator.state = st.rng_state, back.state.rng_state
    assert np.array_equal(a.random(5), b.random(5))
    assert (back.setup, back.params, back.version, back.stage, back.restart,
            back.generation, back.state.n_evaluations, back.done) == (
        ck.setup, ck.params, "9.9", "refine", 2, 7, st.n_evaluations, ck.done)


def test_a_checkpoint_of_the_earlier_layout_is_refused(tmp_path: Path) -> None:
    """Layout 1 kept the population in gains only, not the generator: it cannot resume
    exactly, so it is refused with the way out."""
    old = tmp_path / "old.npz"
    with old.open("wb") as fh:
        np.savez(fh, population=np.ones((5, 3)), header=np.array(
            '{"controller": "pid", "plant": "linear", "objective": "itae", "seed": 0, '
            '"stage": "search", "generation": 3, "done": {}}'))
    with pytest.raises(InputError, match="layout 1.*delete it or run without --resume"):
        load_checkpoint(old)


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
    path = save_checkpoint(tmp_path / "g.toml.partial.npz", _checkpoint(_state(30, 3)))
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
        np.savez(fh, population=np.array([object()], dtype=object),
                 header=np.array('{"format": 2}'))
    with pytest.raises(InputError) as err:
        load_checkpoint(objects)
    assert "pickled objects, which fuzzyservo never loads" in str(err.value)
    assert "allow_pickle" not in str(err.value)
