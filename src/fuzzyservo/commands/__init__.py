"""One module per CLI subcommand; each exposes ``register(subparsers)``.

This package's own module is the table of the subcommands (no import beyond the standard
library), so ``fuzzyservo --help`` and ``--version`` list them without importing any
command: the CLI imports only the module of the command it runs."""

from __future__ import annotations

__all__ = ["COMMANDS", "HELP"]

#: Each subcommand's module (in this package), in the order ``--help`` lists them.
COMMANDS: dict[str, str] = {
    "simulate": "simulate",
    "plot": "plot",
    "metrics": "metrics",
    "tune": "tune",
    "linearize": "linearize",
    "identify": "identify",
    "bode": "bode",
    "surface": "surface",
    "fis": "fis",
    "export": "export",
    "sweep": "sweep",
    "sweep-report": "sweep",
    "reproduce": "reproduce",
    "precompile": "precompile",
    "app": "app",
}

#: Each subcommand's one-line help.
HELP: dict[str, str] = {
    "simulate": "simulate the servo in closed or open loop; CSV, metrics, figure",
    "plot": "plot run CSVs: position and reference, command, alpha",
    "metrics": "step-response metrics of a run CSV",
    "tune": "tune a controller by step-response search",
    "linearize": "linearise the servo: omega_0, damping, gains, eigenvalues",
    "identify": ("identify your axis's model from measured data: fitted parameters with "
                 "uncertainty; an experiment to log"),
    "bode": "closed-loop frequency response: margins, bandwidth; analytic and measured",
    "surface": ("evaluate the paper's du or alpha fuzzy system, or a two-input "
                "fuzzy-system file, on points or a grid"),
    "fis": "evaluate, convert, describe and draw fuzzy-system files (.fis, .fcl, .fll)",
    "export": "the controllers as C99 code and FMUs, the servo as an FMU",
    "sweep": "Monte Carlo and grid sweeps of controllers over plant variations",
    "sweep-report": "offline HTML report of a sweep",
    "reproduce": "reproduce the paper's study (Figs. 3-8, metrics, claims, report)",
    "precompile": "compile the closed-loop kernels once, into the package's cache",
    "app": "a local browser page: tune by looking, the response follows the sliders",
}
