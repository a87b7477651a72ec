"""Per-step export of a run: every recorded signal and the exact contour error, one row per step.

Column names carry their unit (``_m``, ``_m_s``, ``_m_s2``, ``_s``; command-unit signals and the curve
parameter have none), per-axis columns their axis name: ``time_s, theta, reference_position_x_m, ...,
exact_contour_error_m``. Written as CSV, and as Parquet when pyarrow is installed.
"""
from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from ..core.geometry import ExactContourError
from ..errors import BagError
from .outputs import write_atomically
from .scoring import curve_of, read_run

__all__ = ["run_table", "write_csv", "write_parquet", "export_bag"]

# SimulationResult field -> unit suffix ('' for command units and curve parameters)
_SIGNALS = [("time", "_s"), ("theta", ""), ("reference_position", "_m"), ("reference_velocity", "_m_s"),
            ("reference_acceleration", "_m_s2"), ("position", "_m"), ("velocity", "_m_s"),
            ("estimate_theta", ""), ("estimate_vector", "_m"), ("estimate_signed", "_m"), ("correction", ""),
            ("command", "")]


def run_table(result, axes, curve) -> dict:
    """Column name -> (m,) array for every signal of ``result`` (a SimulationResult), per axis where the
    signal has one value per axis, plus the exact contour error (distance to the whole curve)."""
    columns = {}
    for name, unit in _SIGNALS:
        values = np.asarray(getattr(result, name))
        if values.ndim == 1:
            columns[f"{name}{unit}"] = values
        else:
            for i, axis in enumerate(axes):
                columns[f"{name}_{axis}{unit}"] = values[:, i]
    columns["exact_contour_error_m"] = ExactContourError(curve)(result.position, near=result.theta).distance \
        if len(result.time) else np.zeros(0)
    return columns


def write_csv(columns: dict, path) -> Path:
    """The table as CSV, written to a temporary file and renamed (no truncated CSV on a full disk)."""
    def write(tmp):
        with open(tmp, "x", newline="") as stream:
            writer = csv.writer(stream)
            writer.writerow(columns)
            for row in zip(*(values.tolist() for values in columns.values())):
                writer.writerow([repr(v) for v in row])
    return write_atomically(path, write)


def write_parquet(columns: dict, path) -> Path:
    """The table as Parquet (needs pyarrow: a one-line BagError without it)."""
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        raise BagError("Parquet export needs pyarrow (pip install pyarrow); --csv needs nothing more") from None
    table = pa.table({name: np.asarray(values) for name, values in columns.items()})
    return write_atomically(path, lambda tmp: pq.write_table(table, tmp))


def export_bag(bag, csv_dir=None, parquet_dir=None, experiment_text: str | None = None, parsed=None) -> tuple:
    """Export a bag's complete steps to ``csv_dir``/<bag stem>.csv and/or ``parquet_dir``/<bag stem>.parquet
    (``experiment_text`` and ``parsed`` as in :func:`contouring_ros.records.scoring.read_run`).
    Returns (written paths, the reader's warnings)."""
    run = read_run(bag, experiment_text=experiment_text, parsed=parsed)
    columns = run_table(run.result, run.axes, curve_of(run))
    stem = Path(bag).stem
    written = []
    if csv_dir is not None:
        written.append(write_csv(columns, Path(csv_dir) / f"{stem}.csv"))
    if parquet_dir is not None:
        written.append(write_parquet(columns, Path(parquet_dir) / f"{stem}.parquet"))
    return written, run.warnings
