"""trajectory.csv (docs/outputs.md): its writer and the reader of its numeric columns that reports and
campaign tables use; the provenance every summary.json starts with (`testbed.eval.run.summary` writes it)."""

from __future__ import annotations

import csv
import functools
import importlib.metadata
import math
import subprocess
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from testbed.errors import UserError
from testbed.eval.run.summary import SCHEMA_VERSION
from testbed.loop import TickRecord

TRAJECTORY_COLUMNS = ("t", "x", "y", "yaw", "speed", "phys_dev", "msf_dev", "ld_dev", "ld_fresh", "cusum", "mode",
                      "steer", "accel", "attack_stage", "attack_offset", "fused_dev", "r_msf", "r_ld", "k_msf",
                      "k_ld", "heading_used")
@functools.cache
def provenance() -> dict[str, Any]:
    """What produced a run: the summary schema version, the package version and the git commit of the
    source tree (None outside a git checkout; suffixed `-dirty` when it has uncommitted changes)."""
    root = Path(__file__).resolve().parents[3]
    commit: str | None = None
    try:
        head = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True, text=True,
                              timeout=5, check=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, timeout=5, check=True).stdout.strip()
        commit = head + ("-dirty" if dirty else "")
    except (OSError, subprocess.SubprocessError):
        commit = None
    try:
        version = importlib.metadata.version("ld3-testbed")
    except importlib.metadata.PackageNotFoundError:
        version = None
    return {"schema_version": SCHEMA_VERSION, "package_version": version, "git_commit": commit}


def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return "" if not math.isfinite(value) else f"{value:.6f}"
    return str(value)


def write_trajectory(path: Path, rows: Iterable[TickRecord]) -> None:
    with path.open("w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(TRAJECTORY_COLUMNS)
        for r in rows:
            writer.writerow([_cell(getattr(r, c)) for c in TRAJECTORY_COLUMNS])


def read_trajectory(run_dir: Path, columns: Sequence[str]) -> dict[str, np.ndarray]:
    """Numeric `columns` of `run_dir`/trajectory.csv as float arrays, one value per tick; an empty cell (a
    value that was None or non-finite when written) reads as NaN."""
    unknown = [c for c in columns if c not in TRAJECTORY_COLUMNS]
    if unknown:
        raise ValueError(f"trajectory.csv has no column(s) {unknown}")
    path = run_dir / "trajectory.csv"
    out: dict[str, list[float]] = {c: [] for c in columns}
    line = 1
    try:
        with path.open(newline="") as fh:
            reader = csv.DictReader(fh)
            missing = [c for c in columns if c not in (reader.fieldnames or ())]
            for row in () if missing else reader:
                line = reader.line_num
                for c in columns:
                    out[c].append(float(row[c]) if row[c] else math.nan)
    except (UnicodeDecodeError, csv.Error, ValueError, TypeError) as exc:
        raise UserError(f"{path}:{line}: not a trajectory's numbers ({' '.join(str(exc).split())[:120]})") from None
    if missing:
        raise UserError(f"{path}: no column(s) {', '.join(missing)} in its header")
    return {c: np.array(v) for c, v in out.items()}


def chassis_faults(summary: dict[str, Any]) -> list[dict[str, Any]]:
    """The summary's `faults` that the chassis latched (they end the run), leaving out those the defense handled."""
    return [f for f in summary["faults"] if f["source"] == "chassis"]
