"""A run's figures (birdseye.png, and ar_fusion.png where the attack response ran) from what they draw, and the
files a run that defers them leaves (believed.csv: the one input the other outputs lack) and that
`testbed.eval.report.figures_later` reads back (trajectory.csv to six decimals, traffic.csv to millimetres)."""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

import numpy as np

from testbed.eval.run.outputs import TRAJECTORY_COLUMNS
from testbed.loop import TickRecord
from testbed.traffic.record import TrafficLog

BELIEVED = "believed.csv"
"""The believed (MSF) path of a run whose figures were deferred: `x`, `y` per control tick (m, six decimals)."""
BIRDSEYE = "birdseye.png"


@dataclass(frozen=True)
class FigureInputs:
    """What a run's figures draw besides its tick records: the (painted) track, the lane and straddle widths,
    the believed path, the detection and stop times, birdseye.png's title, ar_fusion.png's (None: an unattacked
    run, no such figure), the attack start, the defense's alarm threshold, and the traffic cars' paths and size."""

    track: Any
    lane_width: float
    straddle_dev: float
    believed_xy: np.ndarray
    detection_t: float | None
    stop_t: float | None
    title: str
    fusion_title: str | None = None
    attack_t: float | None = None
    threshold: float | None = None
    traffic: dict[int, np.ndarray] | None = None
    traffic_size: tuple[float, float] = (0.0, 0.0)


def save_run_figures(out_dir: Path, rows: Sequence[TickRecord], inputs: FigureInputs) -> None:
    """birdseye.png, and ar_fusion.png for an attacked run whose rows carry the response's fusion. The drawing
    modules (matplotlib) are imported here: a worker whose runs defer their figures never loads them."""
    from testbed.eval.run.birdseye import save_birdseye
    from testbed.eval.run.fusion_plot import has_fusion, save_fusion_plot

    save_birdseye(out_dir / BIRDSEYE, inputs.track, rows, lane_width=inputs.lane_width,
                  straddle_dev=inputs.straddle_dev, believed_xy=inputs.believed_xy, detection_t=inputs.detection_t,
                  stop_t=inputs.stop_t, title=inputs.title, attack_t=inputs.attack_t, threshold=inputs.threshold,
                  traffic=inputs.traffic, traffic_size=inputs.traffic_size)
    if inputs.fusion_title is not None and has_fusion(rows):
        save_fusion_plot(out_dir / "ar_fusion.png", rows, straddle_dev=inputs.straddle_dev, title=inputs.fusion_title)


def fusion_title(name: str, track: str, attack: Any) -> str | None:
    """ar_fusion.png's title, or None for a run without an attack."""
    return None if attack is None else f"{name} · {track} · {attack.name} · attack response"


def write_believed(path: Path, believed_xy: np.ndarray) -> None:
    with path.open("w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(("x", "y"))
        writer.writerows((f"{x:.6f}", f"{y:.6f}") for x, y in believed_xy)


def read_believed(path: Path) -> np.ndarray:
    with path.open() as fh:
        rows = list(csv.reader(fh))[1:]
    return np.array([(float(x), float(y)) for x, y in rows]).reshape(-1, 2)


_KINDS = {f.name: f.type for f in fields(TickRecord)}


def _value(column: str, text: str) -> Any:
    kind = _KINDS[column]
    if kind == "str":
        return text
    if text == "":
        return math.nan if kind == "float" else None
    if kind == "int":
        return int(text)
    if kind == "str | None":
        return text
    return float(text)


def read_rows(run_dir: Path) -> list[TickRecord]:
    """trajectory.csv back as tick records (an empty cell: None, or NaN for a column that is never None)."""
    with (run_dir / "trajectory.csv").open() as fh:
        return [TickRecord(**{c: _value(c, row[c]) for c in TRAJECTORY_COLUMNS}) for row in csv.DictReader(fh)]


def read_traffic(path: Path) -> dict[int, np.ndarray]:
    """traffic.csv back as each car's (x, y, yaw) path (`TrafficLog.paths`)."""
    log = TrafficLog()
    with path.open() as fh:
        for row in csv.DictReader(fh):
            log.rows.append((float(row["t"]), int(row["id"]), int(row["lane"]), float(row["x"]), float(row["y"]),
                             float(row["yaw"]), float(row["speed"])))
    return log.paths()
