"""Shared CLI options that select the servo parameters: ``--set``, ``--params``, ``--param``.

Order of application: the named set (``--set``, default ``paper``), then the TOML file
(``--params FILE.toml``, ``[group] field = value`` tables overriding the set), then every
``--param group.field=value`` in the order given. The result is validated once.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from ..paper.published import SET_NAMES
from ..plant import ServoParams, read_overrides_toml
from ..run import DEFAULT_SET, parse_param, servo_params

__all__ = ["DEFAULT_SET", "add_plant_arguments", "overrides_from_args", "params_from_args",
           "params_given", "parse_param", "set_name"]



def add_plant_arguments(parser: argparse.ArgumentParser) -> None:
    """Add ``--set``, ``--params`` and repeated ``--param`` to ``parser``."""
    group = parser.add_argument_group("plant parameters")
    group.add_argument("--set", dest="param_set", default=None, metavar="NAME",
                       help=f"named parameter set: {', '.join(SET_NAMES)} (default: paper)")
    group.add_argument("--params", dest="param_file", type=Path, default=None,
                       metavar="FILE.toml",
                       help="TOML file of [group] field = value overrides (SI units)")
    group.add_argument("--param", dest="param_overrides", action="append", default=[],
                       metavar="GROUP.FIELD=VALUE",
                       help="override one parameter in SI units, e.g. "
                            "valve.null_leakage=0 (repeatable)")


def set_name(args: Any) -> str:
    """The parameter set ``--set`` names (``paper`` when not given)."""
    return str(args.param_set or DEFAULT_SET)


def params_given(args: Any) -> bool:
    """Whether any of ``--set``, ``--params``, ``--param`` was given."""
    return bool(args.param_set is not None or args.param_file is not None
                or args.param_overrides)


def overrides_from_args(args: Any) -> dict[str, float]:
    """Every override in force, ``{"group.field": value}``: the ``--params`` file's, then each
    ``--param`` in the order given (a later one wins). Recorded by ``tune`` and ``reproduce``
    so that a result names every parameter that differs from its set."""
    overrides: dict[str, Any] = {}
    if args.param_file is not None:
        overrides.update(read_overrides_toml(args.param_file))
    for text in args.param_overrides:
        name, value = parse_param(text)
        overrides.pop(name, None)  # keep the order in which they take effect
        overrides[name] = value
    return overrides


def params_from_args(args: Any) -> ServoParams:
    """Build the :class:`ServoParams` selected by the options of :func:`add_plant_arguments`."""
    return servo_params(set_name(args), overrides_from_args(args))
