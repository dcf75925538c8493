"""fuzzyservo.sweep: robustness at scale. Monte Carlo and grid sweeps of controllers over plant
variations, run chunk by chunk (locally or on Dask) into a resumable Parquet dataset, and the
report that reads it (docs/sweep.md)."""

from .dataset import Manifest, read_manifest, read_table, table_digest
from .run import columns, compute_chunk, run_sweep
from .sampling import Points, points
from .spec import ControllerEntry, SweepSpec, Variation, load_spec, parse_spec

__all__ = [
    "ControllerEntry",
    "Manifest",
    "Points",
    "SweepSpec",
    "Variation",
    "columns",
    "compute_chunk",
    "load_spec",
    "parse_spec",
    "points",
    "read_manifest",
    "read_table",
    "run_sweep",
    "table_digest",
]
