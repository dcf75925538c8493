"""fuzzyservo.files: the files the package reads and writes (gains TOML, checkpoints, run CSVs).

The layer that does file I/O for the analysis below it: the tuner returns records, and this
package turns them into files and back.
"""

from __future__ import annotations

from .checkpoint import checkpoint_path, load_checkpoint, save_checkpoint
from .gains import GainsFile, load_controller, read_gains_file, read_gains_toml, write_gains_toml
from .runs import RunData, read_csv_columns, read_run_csv

__all__ = [
    "GainsFile",
    "RunData",
    "checkpoint_path",
    "load_checkpoint",
    "load_controller",
    "read_csv_columns",
    "read_gains_file",
    "read_gains_toml",
    "read_run_csv",
    "save_checkpoint",
    "write_gains_toml",
]
