"""Open-loop replay of a recorded drive (`ld3 replay DRIVE`): a defense runs again over what LD3's detection
read at each camera frame of a run.mcap the testbed wrote (`/ld3/input`: the lane detection and the paired
localization estimate), on the map the run drove; the response's fusion runs as a shadow after the alarm.

Writes replay.csv (t, D_MSF, D_LD, the CUSUM statistic, mode, and in the response the fused deviation and the
trust ratios) and replay.png (the deviations and the statistic against τ; needs matplotlib), and returns the
detection time. The scenario's track and `[defense]` parameters come from the summary.json beside the MCAP
unless given.
"""

from __future__ import annotations

import csv
import json
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from testbed.defense.bicycle import BicycleCoefficients
from testbed.defense.registry import DEFENSES, defense_settings
from testbed.errors import UserError
from testbed.eval.run.ld3_input import ld3_input_from_message
from testbed.eval.run.summary import read_summary_object
from testbed.lane_detection import LaneDetection
from testbed.localization.estimate import LocalizationEstimate
from testbed.presets import build_track
from tracks.semantic_map import TrackMap

TOPIC = "/ld3/input"
COLUMNS = ("t", "msf_dev", "ld_dev", "cusum", "mode", "fused_dev", "r_msf", "r_ld")


@dataclass(frozen=True)
class ReplayResult:
    """The replay's rows (one per camera frame, `COLUMNS`), its detection time (None: no alarm) and τ."""

    rows: list[dict[str, Any]]
    detection_time_s: float | None
    tau: float | None


def read_inputs(path: Path) -> Iterator[tuple[LaneDetection, LocalizationEstimate]]:
    """The `/ld3/input` messages of a run.mcap in log-time order."""
    try:
        from mcap.reader import make_reader
    except ImportError:
        raise UserError("replaying run.mcap needs the mcap package: pip install 'ld3-testbed[record]'") from None
    with path.open("rb") as stream:
        found = False
        messages = None
        while True:
            try:
                messages = messages or make_reader(stream).iter_messages(topics=[TOPIC])
                message = next(messages, None)
                if message is None:
                    break
                inputs = ld3_input_from_message(json.loads(message[2].data))
            except Exception as exc:  # the mcap reader, its decompressors and the JSON decoder raise their own types
                problem = " ".join(f"{type(exc).__name__}: {exc}".split())[:200]
                raise UserError(f"{path}: not a readable run.mcap ({problem})") from None
            found = True
            yield inputs
    if not found:
        raise UserError(f"{path} has no {TOPIC} channel: record the drive with `ld3 run ... --record`")


def drive_settings(path: Path) -> dict[str, Any]:
    """Track, defense and `[defense]` parameters of the run that wrote `path` (its summary.json), else {}."""
    summary = path.parent / "summary.json"
    if not summary.is_file():
        return {}
    data = read_summary_object(summary)
    settings = {"track": data.get("track"), "defense": data.get("defense"),
                "defense_params": data.get("defense_params") or {}}
    for key, kind in (("track", str), ("defense", str), ("defense_params", dict)):
        if settings[key] is not None and not isinstance(settings[key], kind):
            raise UserError(f"{summary}: {key} is not a {'table' if kind is dict else 'string'}")
    return settings


def replay_drive(path: Path, track: str, defense: str = "ld3",
                 defense_params: Mapping[str, Any] | None = None) -> ReplayResult:
    """Run `defense` over the drive's inputs on the map of `track`."""
    _, params = defense_settings(defense, dict(defense_params or {}))
    model = DEFENSES.get(defense).factory(params, BicycleCoefficients())
    smap = TrackMap(build_track(track))
    rows: list[dict[str, Any]] = []
    for ld, est in read_inputs(path):
        model.on_lane_detection(ld, est, smap)
        model.pose_for_control(est, smap)
        status = model.status()
        monitor = getattr(model, "monitor", None)
        responding = model.mode == "ar"
        rows.append({"t": ld.timestamp, "msf_dev": getattr(monitor, "d_msf", None),
                     "ld_dev": getattr(monitor, "d_ld", None), "cusum": status.cusum, "mode": model.mode,
                     "fused_dev": status.fused_dev if responding else None,
                     "r_msf": status.r_msf if responding else None, "r_ld": status.r_ld if responding else None})
    return ReplayResult(rows, model.status().detection_time, model.alarm_threshold)


def write_replay(out_dir: Path, result: ReplayResult, title: str) -> list[str]:
    """replay.csv, and replay.png where matplotlib is installed; the names written."""
    out_dir.mkdir(parents=True, exist_ok=True)
    with (out_dir / "replay.csv").open("w", newline="") as fh:
        writer = csv.DictWriter(fh, COLUMNS)
        writer.writeheader()
        writer.writerows({k: ("" if v is None else v) for k, v in row.items()} for row in result.rows)
    try:
        from matplotlib.figure import Figure
    except ImportError:
        return ["replay.csv"]

    t = [r["t"] for r in result.rows]
    fig = Figure(figsize=(9, 6))
    dev, stat = fig.subplots(2, 1, sharex=True)
    for key, label in (("msf_dev", "D_MSF"), ("ld_dev", "D_LD"), ("fused_dev", "fused d")):
        dev.plot(t, [float("nan") if r[key] is None else r[key] for r in result.rows], label=label)
    dev.set_ylabel("lateral deviation (m, + left)")
    dev.legend()
    stat.plot(t, [float("nan") if r["cusum"] is None else r["cusum"] for r in result.rows], label="CUSUM")
    if result.tau is not None:
        stat.axhline(result.tau, color="k", linestyle="--", label="τ")
    for axis in (dev, stat):
        if result.detection_time_s is not None:
            axis.axvline(result.detection_time_s, color="r", linestyle=":", label=None)
    stat.set_xlabel("time (s)")
    stat.set_ylabel("statistic (m)")
    stat.legend()
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(out_dir / "replay.png", dpi=110)
    return ["replay.csv", "replay.png"]
