"""A run's figures (birdseye.png, and ar_fusion.png where the attack response ran): drawn when the run ends, or
later from its folder (`ld3 figures`), where a campaign that defers them (a search's trials) leaves the one input
the other outputs lack, the believed path, in believed.csv.

Drawn later, the figures read trajectory.csv (six decimals) and traffic.csv (millimetres) back and rebuild the
track, the attack and the defense from the summary's resolved scenario: the same picture as at the run's end up
to that rounding.
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

import numpy as np

from testbed.errors import UserError
from testbed.eval.birdseye import save_birdseye
from testbed.eval.fusion_plot import has_fusion, save_fusion_plot
from testbed.eval.outputs import TRAJECTORY_COLUMNS
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
    """birdseye.png, and ar_fusion.png for an attacked run whose rows carry the response's fusion."""
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


def run_folders(root: Path) -> list[Path]:
    """`root` itself when it is a run folder (summary.json and trajectory.csv), else every run folder under it;
    a one-line UserError when there are none."""
    if not root.is_dir():
        raise UserError(f"{root} is not a folder; name a run folder or a campaign or search folder")
    found = sorted(p.parent for p in root.rglob("summary.json") if (p.parent / "trajectory.csv").is_file()
                   and not any(part.startswith(".") for part in p.parent.relative_to(root).parts))
    if not found:
        raise UserError(f"{root} holds no run folder (summary.json beside trajectory.csv)")
    return found


def draw_later(run_dir: Path) -> bool:
    """Draw the figures of a run folder whose run deferred them (believed.csv, no birdseye.png) from its files;
    False (nothing drawn) for any other folder."""
    from testbed.defense.registry import DEFENSES
    from testbed.eval.runner import SimRun
    from testbed.eval.scenario import ALWAYS_READ, Scenario

    if (run_dir / BIRDSEYE).exists() or not (run_dir / BELIEVED).exists():
        return False
    try:
        summary = json.loads((run_dir / "summary.json").read_text())
        resolved = dict(summary["resolved_scenario"])
        reads = DEFENSES.get(resolved["defense"]).reads | ALWAYS_READ
        resolved["defense_params"] = {k: v for k, v in resolved["defense_params"].items() if k in reads}
        sc = Scenario.model_validate(resolved)
    except (ValueError, TypeError, KeyError, AttributeError) as exc:
        why = " ".join(str(exc).split())[:200]
        raise UserError(f"{run_dir}/summary.json holds no scenario to draw the figures of ({type(exc).__name__}: "
                        f"{why})") from None
    sim = SimRun(sc)  # builds the painted track, the attack and the defense; never steps
    try:
        parts = sim.parts
        traffic = run_dir / "traffic.csv"
        inputs = FigureInputs(
            parts.track, parts.lane_width, summary["lane_straddle_dev_m"], read_believed(run_dir / BELIEVED),
            summary["detection_time_s"], summary["stop_time_s"],
            f"{sc.name} · {sc.track} · defense {sc.defense} · {summary['consequence']}",
            fusion_title=fusion_title(sc.name, sc.track, parts.attack),
            attack_t=parts.attack.start_time if parts.attack is not None else None,
            threshold=parts.defense.alarm_threshold,
            traffic=read_traffic(traffic) if traffic.exists() else None,
            traffic_size=(parts.traffic.length, parts.traffic.width) if parts.traffic is not None else (0.0, 0.0))
    finally:
        sim.close()
    save_run_figures(run_dir, read_rows(run_dir), inputs)
    return True
