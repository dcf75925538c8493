"""The compiled core's cache and notice (fuzzyservo._jit): the cache is keyed by the sources,
so an edited callee is compiled afresh, never run stale; it lives in a user cache folder, not
in the install; a cold compile says so on standard error and a warm run says nothing."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import fuzzyservo
from fuzzyservo import _jit

PACKAGE = Path(fuzzyservo.__file__).resolve().parent

#: The per-step API of a P controller: u = kp e for |kp e| < 1 (a small compile).
STEP = ("from fuzzyservo.control import PIDController\n"
        "c = PIDController(dt=1e-3, kp=2.0)\n"
        "u, _ = c.step(c.initial_state(), 0.1, 0.0)\n"
        "from fuzzyservo import _jit\n"
        "print(repr(u), _jit.cache_dir())\n")


def _copy(tmp: Path) -> Path:
    """A scratch copy of the package (its sources only) under ``tmp/src``."""
    dst = tmp / "src" / "fuzzyservo"
    shutil.copytree(PACKAGE, dst, ignore=shutil.ignore_patterns("__pycache__", "*.nbi",
                                                                "*.nbc"))
    return dst.parent


def _run(src: Path, code: str, env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    full = {k: v for k, v in os.environ.items()
            if k not in ("NUMBA_CACHE_DIR", "FUZZYSERVO_CACHE_DIR", "XDG_CACHE_HOME")}
    full.update(env, PYTHONPATH=str(src), PYTHONDONTWRITEBYTECODE="1")
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env=full, timeout=600, check=False, cwd=src)


def test_editing_a_callee_in_another_file_compiles_afresh(tmp_path: Path) -> None:
    src = _copy(tmp_path)
    env = {"FUZZYSERVO_CACHE_DIR": str(tmp_path / "cache")}
    first = _run(src, STEP, env)
    assert first.returncode == 0, first.stderr
    u, folder = first.stdout.split()
    assert float(u) == 2.0 * 0.1
    # again: loaded from the cache, the same answer and folder
    again = _run(src, STEP, env)
    assert again.stdout.split() == [u, folder]
    # the law's step (control/pid.py) is a callee of the per-step kernel (control/law.py,
    # unchanged): numba alone would load the stale kernel; here the cache folder changes
    pid = src / "fuzzyservo" / "control" / "pid.py"
    text = pid.read_text()
    assert text.count("    s[S.ed_prev] = ed\n    return u\n") == 1
    pid.write_text(text.replace("    s[S.ed_prev] = ed\n    return u\n",
                                "    s[S.ed_prev] = ed\n    return 0.5 * u\n"))
    edited = _run(src, STEP, env)
    assert edited.returncode == 0, edited.stderr
    u2, folder2 = edited.stdout.split()
    assert float(u2) == 0.5 * 2.0 * 0.1
    assert folder2 != folder and Path(folder).is_dir() and Path(folder2).is_dir()


def test_the_cache_is_a_user_folder_not_the_install(tmp_path: Path) -> None:
    src = _copy(tmp_path)
    env = {"XDG_CACHE_HOME": str(tmp_path / "xdg")}
    proc = _run(src, STEP, env)
    assert proc.returncode == 0, proc.stderr
    folder = Path(proc.stdout.split()[1])
    assert folder.parent == tmp_path / "xdg" / "fuzzyservo"
    assert any(folder.rglob("*.nbi"))  # the kernels' index files are there
    assert not any((src / "fuzzyservo").rglob("*.nb[ic]"))  # and nothing in the install
    # no writable user cache folder (a file where the folder would be): the temporary folder
    (tmp_path / "blocked").write_text("")
    proc = _run(src, STEP, {"XDG_CACHE_HOME": str(tmp_path / "blocked")})
    assert proc.returncode == 0, proc.stderr
    assert Path(proc.stdout.split()[1]).parent.name.startswith("fuzzyservo-")


def test_a_cold_compile_says_so_and_a_warm_run_says_nothing(tmp_path: Path) -> None:
    src = _copy(tmp_path)
    env = {"FUZZYSERVO_CACHE_DIR": str(tmp_path / "cache")}
    code = ("import sys\nfrom fuzzyservo.cli import main\n"
            "sys.exit(main(['simulate', '--plant', 'linear', '--controller', 'pid', "
            "'--gains', 'kp=10,ki=1,kd=0.01', '--reference', 'step:0.05', '--duration', "
            "'0.2', '--metrics']))\n")
    cold = _run(src, code, env)
    assert cold.returncode == 0, cold.stderr
    lines = cold.stderr.splitlines()
    assert lines, "a cold compile printed nothing"
    assert lines[0].startswith("fuzzyservo: compiling the simulation kernels (numba; once "
                               "per install, then they load from ")
    assert "the closed loop on the linear plant for PID" in cold.stderr
    assert any(line.startswith("fuzzyservo: compiled ") for line in lines)
    warm = _run(src, code, env)
    assert warm.returncode == 0 and warm.stderr == ""
    assert warm.stdout == cold.stdout


def test_the_digest_covers_every_source_and_the_compiler() -> None:
    digest = _jit.source_digest()
    assert len(digest) == 16 and int(digest, 16) >= 0
    assert _jit.cache_dir().name == digest


@pytest.mark.parametrize("key", ["bad key", "a/b", ""])
def test_a_specialisation_key_is_a_name(key: str) -> None:
    def tpl(x: float) -> float:
        return x

    with pytest.raises(ValueError, match="specialization key"):
        _jit.specialize([_jit.template(tpl)], {}, key=key, title="t")
