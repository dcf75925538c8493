"""The export targets, registered once, and the functions behind ``fuzzyservo export``.

- ``c``: a registered controller as ``NAME.h`` and ``NAME.c`` (C99, standard library only).
- ``fmu``: a controller, or the servo, as an FMI 2.0 co-simulation FMU for 64-bit Linux.
- ``st``: a registered controller as IEC 61131-3 Structured Text for PLCs (``NAME.st``, the
  function block, and ``NAME_example.st``, a program and configuration running it).

The files are written only after everything has been generated (and, for an FMU, compiled):
an error leaves the output as it was. A C export goes into a folder that is new, empty or
holds only the two files of an earlier export of the same name; anything else is refused
(likewise the Structured Text's two files).
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import Any

from .._io import check_output_path, write_bytes_atomic, write_texts_atomic
from ..errors import InputError
from ..registry import controller_kind
from ._c import Real
from ._st import StReal, check_st_name
from .controller_c import CController, check_c_name, emit_controller
from .fmu import controller_fmu, servo_fmu
from .st import STController, emit_st

__all__ = [
    "EXPORT_TARGETS",
    "ExportTarget",
    "check_c_folder",
    "export_c",
    "export_controller_fmu",
    "export_servo_fmu",
    "export_st",
    "generate_st",
    "export_target_names",
    "generate_c",
]


@dataclass(frozen=True, slots=True, kw_only=True)
class ExportTarget:
    """One export target.

    Parameters
    ----------
    name : str
        The name (``fuzzyservo export NAME``).
    title : str
        What it writes, for help texts.
    writes : str
        What ``--out`` names (a folder or a file).
    """

    name: str
    title: str
    writes: str


_TARGETS: dict[str, ExportTarget] = {
    "c": ExportTarget(name="c", title="a controller as C99 code (NAME.h, NAME.c)",
                      writes="DIR"),
    "fmu": ExportTarget(name="fmu", title="a controller or the servo as an FMI 2.0 "
                        "co-simulation FMU (64-bit Linux)", writes="FILE.fmu"),
    "st": ExportTarget(name="st", title="a controller as IEC 61131-3 Structured Text for PLCs "
                       "(NAME.st, NAME_example.st)", writes="DIR"),
}

#: Every export target by name (read-only).
EXPORT_TARGETS: Mapping[str, ExportTarget] = MappingProxyType(_TARGETS)


def export_target_names() -> tuple[str, ...]:
    """The registered export targets, in order."""
    return tuple(_TARGETS)


def generate_c(kind_name: str, gains: Mapping[str, float], *, ts: float,
               systems: Mapping[str, Any] | None = None,
               options: Mapping[str, Any] | None = None, real: Real = "double",
               name: str | None = None,
               systems_record: Sequence[tuple[str, str, str]] = (),
               command: str = "") -> CController:
    """The C code of the registered controller ``kind_name`` (nothing written).

    Parameters
    ----------
    kind_name : str
        Registered controller name (``fuzzyservo.registry.controller_names()``).
    gains : mapping of str to float
        Its gains [the registry's units]; missing ones take their defaults.
    ts : float
        Sample time [s].
    systems : mapping, optional
        Fuzzy systems by role (default the paper's), as the registry takes them.
    options : mapping, optional
        Controller options the kind takes (anti-windup, limits, fuzzy PI conventions).
    real : {"double", "float"}
        Arithmetic type of the code.
    name : str, optional
        Prefix of the public C identifiers (default ``kind_name``).
    systems_record : sequence of (role, source, sha256)
        Systems read from files, named in the code's comment block.
    command : str
        The command line, recorded in the comment block.

    Raises
    ------
    ParameterError
        Unknown controller, bad gains or options, a bad name or type.
    """
    kind = controller_kind(kind_name)
    checked = kind.check_gains(gains)
    controller = kind.build(checked, dt=ts, systems=systems, options=options)
    return emit_controller(kind, checked, controller,
                           name=check_c_name(kind_name if name is None else name),
                           real=real, systems=systems_record, command=command)


def generate_st(kind_name: str, gains: Mapping[str, float], *, ts: float,
                systems: Mapping[str, Any] | None = None,
                options: Mapping[str, Any] | None = None, real: StReal = "LREAL",
                name: str | None = None,
                systems_record: Sequence[tuple[str, str, str]] = (),
                command: str = "") -> STController:
    """The Structured Text of the registered controller ``kind_name`` (nothing written);
    the arguments as :func:`generate_c`'s, ``real`` ``"LREAL"`` or ``"REAL"``, the block's
    ``name`` by default ``<kind>_ctl`` (``PID`` and other standard names are taken).

    Raises
    ------
    ParameterError
        Unknown controller, bad gains or options, a bad name or type, a general fuzzy system.
    """
    kind = controller_kind(kind_name)
    block = check_st_name(f"{kind_name}_ctl" if name is None else name)
    checked = kind.check_gains(gains)
    controller = kind.build(checked, dt=ts, systems=systems, options=options)
    return emit_st(kind, checked, controller, name=block, real=real,
                   systems=systems_record, command=command)


def export_st(st: STController, out: str | Path) -> tuple[Path, Path]:
    """Write ``st``'s two files into the folder ``out`` (new, empty, or holding only an
    earlier export of the same name), as one (``_io.write_texts_atomic``); returns the
    block's and the example's paths."""
    files = st.files()
    folder = check_c_folder(out, st.name, files=tuple(files))
    try:
        folder.mkdir(exist_ok=True)
    except OSError as exc:
        raise InputError(f"--out {str(folder)!r}: cannot create the folder ({exc.strerror})"
                         ) from None
    paths = {folder / n: text for n, text in files.items()}
    write_texts_atomic(paths)
    block, example = paths
    return block, example


def check_c_folder(out: str | Path, name: str, files: Sequence[str] | None = None) -> Path:
    """Check that ``out`` may receive ``files`` (by default ``NAME.h`` and ``NAME.c``): it
    does not exist (its parent does), or it is a folder that is empty or holds only those
    files.

    Raises
    ------
    InputError
        Anything else (the message names the first other file).
    """
    p = Path(out)
    names = list(files) if files is not None else [f"{name}.h", f"{name}.c"]
    ours = set(names)
    listed = " and ".join(names)
    if p.exists() and not p.is_dir():
        raise InputError(f"--out {str(p)!r} is a file; give a folder for {listed}")
    if p.is_dir():
        others = sorted(e.name for e in p.iterdir() if e.name not in ours)
        if others:
            raise InputError(
                f"--out {str(p)!r} already holds other files ({', '.join(others[:3])}"
                f"{', ...' if len(others) > 3 else ''}); give a new or empty folder (only "
                f"{listed} of an earlier export are replaced)")
        if not os.access(p, os.W_OK | os.X_OK):
            raise InputError(f"--out {str(p)!r} is not writable")
        return p
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.is_dir():
        raise InputError(f"--out {str(p)!r}: folder {str(parent)!r} does not exist")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise InputError(f"--out {str(p)!r}: folder {str(parent)!r} is not writable")
    return p


def export_c(cc: CController, out: str | Path) -> tuple[Path, Path]:
    """Write ``cc``'s header and source into the folder ``out`` (see :func:`check_c_folder`);
    returns their paths. The two are written as one (``_io.write_texts_atomic``): an error
    or an interruption leaves the previous pair, never one old and one new file; and should
    a pair ever be mixed, the source refuses to compile with the header of another export (a
    stamp both carry)."""
    folder = Path(out)
    check_c_folder(folder, cc.name)
    try:
        folder.mkdir(exist_ok=True)
    except OSError as exc:
        raise InputError(f"--out {str(folder)!r}: cannot create the folder ({exc.strerror})"
                         ) from None
    hdr, src = folder / f"{cc.name}.h", folder / f"{cc.name}.c"
    files = cc.files()
    write_texts_atomic({src: files[src.name], hdr: files[hdr.name]})
    return hdr, src


def export_controller_fmu(cc: CController, out: str | Path, *, command: str = "") -> Path:
    """Build the controller FMU of ``cc`` and write it to ``out`` (replaced atomically).

    Raises
    ------
    InputError
        ``out`` cannot be written.
    CompilerError
        No C compiler, or it failed.
    """
    path = check_output_path(out, option="--out")
    if path.suffix.lower() != ".fmu":
        raise InputError(f"--out {str(path)!r}: an FMU's file name ends in .fmu")
    kind = controller_kind(cc.kind)
    data = controller_fmu(cc, kind_title=kind.title, command=command)
    return write_bytes_atomic(path, data)


def export_servo_fmu(plant: Any, out: str | Path, *, plant_name: str, ts: float,
                     delay: float, name: str | None = None, description: str = "") -> Path:
    """Build the servo FMU of ``plant`` (a built :class:`~fuzzyservo.sim.LinearPlant` or
    :class:`~fuzzyservo.sim.NonlinearPlant`) at sample time ``ts`` [s] with transport delay
    ``delay`` [s], and write it to ``out`` (replaced atomically).

    Raises
    ------
    InputError
        ``out`` cannot be written.
    ParameterError
        A bad sample time, delay or name.
    CompilerError
        No C compiler, or it failed.
    """
    from .plant_c import emit_servo, plant_fragment

    path = check_output_path(out, option="--out")
    if path.suffix.lower() != ".fmu":
        raise InputError(f"--out {str(path)!r}: an FMU's file name ends in .fmu")
    identifier = check_c_name("servo_" + plant_name.replace("-", "_") if name is None else name)
    servo = emit_servo(plant, ts=ts, delay=delay)
    data = servo_fmu(
        servo, identifier=identifier, plant_name=plant_name,
        description=description or f"{plant_name} servo model of fuzzyservo",
        units=servo.units, outputs=servo.outputs, descriptions=servo.descriptions, ts=ts,
        u_trim=float(plant.u0), delay=delay, plant_code=plant_fragment() + "\n" + servo.source,
        force_op=servo.force_op if servo.force_input else None)
    return write_bytes_atomic(path, data)
