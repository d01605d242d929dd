"""Closed-loop lane-detection accuracy per condition × preset (`ld3 ld closed-loop`).

Each cell drives a held-out track seed (`HELD_OUT_SEEDS`) of one preset in one condition for `duration`
seconds with the detector, MSF localization and no defense: control follows the MSF, so the detections never
steer the car and one drive serves both columns. Per control tick the error is |D_LD − phys_dev|, D_LD from
Alg. 3 as the loop computes it (map lane width at the MSF pose, last D held between frames and while no line is
valid): once of the tracked detections the loop used, once of the raw detections of the same frames.
A preset too short for the duration is driven slower, so that it lasts the duration.
"""

from __future__ import annotations

import contextlib
import math
import multiprocessing
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

import numpy as np
from tqdm import tqdm

from testbed.conditions import get_condition
from testbed.defense.ld_deviation import LdDeviation
from testbed.errors import UserError
from testbed.eval.run_build import END_MARGIN_M
from testbed.eval.runner import SimRun
from testbed.eval.scenario import load_scenario
from testbed.lane_detection import CameraFrame, LaneDetection, LaneDetector
from testbed.perception.registry import make_detector
from testbed.perception.seeds import Cell, cells
from testbed.presets import TRACKS
from tracks.map_api import OffMapError
from tracks.pose import Pose
from tracks.presets import load_track
from vehicles.camera_rig import CameraRig
from vehicles.params import get_vehicle

MEAN_TARGET_M = {"day": 0.05}
"""Mean |D_LD error| target with tracking per condition (`MEAN_TARGET_OTHER_M` elsewhere)."""
MEAN_TARGET_OTHER_M = 0.08
P99_TARGET_M = 0.20


class _RawTap(LaneDetector):
    """Passes a detector's output through, keeping each raw detection with the MSF pose of its tick."""

    def __init__(self, detector: LaneDetector) -> None:
        self.detector = detector
        self.reports_variance = detector.reports_variance
        self.reads_camera = detector.reads_camera
        self.name = getattr(detector, "name", type(detector).__name__)
        self.pose_now = lambda: None
        self.frames: list[tuple[LaneDetection, Pose | None]] = []

    def detect(self, frame: CameraFrame) -> LaneDetection:
        ld = self.detector.detect(frame)
        self.frames.append((ld, self.pose_now()))
        return ld


def error_stats(err: np.ndarray) -> dict[str, float | None]:
    e = err[np.isfinite(err)]
    if not len(e):
        return {"mean_m": None, "p99_m": None, "max_m": None}
    return {"mean_m": float(e.mean()), "p99_m": float(np.percentile(e, 99)), "max_m": float(e.max())}


def drive(cell: Cell, detector: str = "neural", duration: float = 30.0, seed: int = 0,
          existence_threshold: float = 0.5) -> dict:
    """Drive one cell: what was driven, and the per-tick errors (m) without (`raw`) and with (`tracked`)
    tracking."""
    base = load_scenario(cell.preset)
    spec = f"{cell.preset}@{cell.track_seed}"
    track = load_track(spec)
    room = track.length - base.start_s - END_MARGIN_M
    speed = min(base.speed, room / duration)
    sc = base.with_overrides(track=spec, condition=cell.condition, duration=duration, speed=speed, seed=seed,
                             detector=detector, localization="msf", defense="none", name=f"ld-{cell.preset}")
    rig = CameraRig(get_vehicle(sc.vehicle).camera)
    tap = _RawTap(make_detector(detector, track=track, rig=rig, rng=np.random.default_rng(seed)))
    sim = SimRun(sc, detector=tap, tracking=True)
    tap.pose_now = lambda: sim.loop.last_estimate.pose
    try:
        result = sim.run()
    finally:
        sim.close()
    rows = result.rows
    phys = np.array([np.nan if r.phys_dev is None else r.phys_dev for r in rows])
    tracked = np.array([np.nan if r.ld_dev is None else r.ld_dev for r in rows])
    raw = np.full(len(rows), np.nan)
    alg3, frames, last = LdDeviation(existence_threshold), iter(tap.frames), None
    for i, r in enumerate(rows):
        if r.ld_fresh:
            ld, pose = next(frames)
            with contextlib.suppress(OffMapError):
                last = alg3.update(ld, sim.smap.lane_width(pose))
        raw[i] = np.nan if last is None else last
    return {"preset": cell.preset, "condition": cell.condition, "track": spec, "speed_mps": round(speed, 2),
            "sim_time_s": round(len(rows) / sim.loop.rates.control_hz, 2), "frames": len(tap.frames),
            "raw": np.abs(raw - phys), "tracked": np.abs(tracked - phys)}


def _one_thread() -> None:
    import torch

    torch.set_num_threads(1)


def run_closed_loop(presets: list[str], conditions: list[str], detector: str = "neural", duration: float = 30.0,
                    workers: int = 1, progress: bool = False) -> list[dict]:
    """Drive every cell (one torch thread each; `workers` processes at once), results in cell order; a bad
    preset, condition or duration is a UserError before any drive."""
    if not (math.isfinite(duration) and duration > 0):
        raise UserError(f"--duration must be a time > 0 s, got {duration}")
    for preset in presets:
        TRACKS.get(preset)
    for condition in conditions:
        get_condition(condition)
    todo = cells(presets, conditions)
    bar = tqdm(total=len(todo), desc="closed loop", unit="drive", disable=not progress)
    if workers <= 1:
        _one_thread()
        out = []
        for cell in todo:
            bar.set_postfix_str(f"{cell.preset} {cell.condition}")
            out.append(drive(cell, detector, duration))
            bar.update(1)
        return out
    results: dict[Cell, dict] = {}
    with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn"),
                             initializer=_one_thread) as pool:
        futures = {pool.submit(drive, cell, detector, duration): cell for cell in todo}
        for future in as_completed(futures):
            results[futures[future]] = future.result()
            bar.update(1)
    return [results[cell] for cell in todo]


def _f(v: float | None) -> str:
    return "-" if v is None else f"{v:.3f}"


def mean_target(condition: str) -> float:
    return MEAN_TARGET_M.get(condition, MEAN_TARGET_OTHER_M)


def markdown_table(results: list[dict]) -> str:
    """Per condition × preset, then per condition (the ticks of its presets pooled), raw against tracked, with
    the targets."""
    lines = ["| condition | preset | track | s | raw mean | raw p99 | raw max | tracked mean | tracked p99 "
             "| tracked max |", "|---|---|---|---|---|---|---|---|---|---|"]
    for r in results:
        raw, tracked = error_stats(r["raw"]), error_stats(r["tracked"])
        lines.append(f"| {r['condition']} | {r['preset']} | {r['track']} | {r['sim_time_s']:g} "
                     f"| {_f(raw['mean_m'])} | {_f(raw['p99_m'])} | {_f(raw['max_m'])} "
                     f"| {_f(tracked['mean_m'])} | {_f(tracked['p99_m'])} | {_f(tracked['max_m'])} |")
    lines += ["", f"Per condition (every tick of its presets); targets with tracking: mean ≤ "
              f"{MEAN_TARGET_M['day']:.2f} m in day, ≤ {MEAN_TARGET_OTHER_M:.2f} m otherwise, p99 ≤ "
              f"{P99_TARGET_M:.2f} m.", "",
              "| condition | raw mean | raw p99 | raw max | tracked mean | tracked p99 | tracked max "
              "| meets targets |", "|---|---|---|---|---|---|---|---|"]
    for cond in dict.fromkeys(r["condition"] for r in results):
        group = [r for r in results if r["condition"] == cond]
        s = {k: error_stats(np.concatenate([r[k] for r in group])) for k in ("raw", "tracked")}
        ok = (s["tracked"]["mean_m"] is not None and s["tracked"]["mean_m"] <= mean_target(cond)
              and s["tracked"]["p99_m"] <= P99_TARGET_M)
        lines.append(f"| {cond} | {_f(s['raw']['mean_m'])} | {_f(s['raw']['p99_m'])} | {_f(s['raw']['max_m'])} "
                     f"| {_f(s['tracked']['mean_m'])} | {_f(s['tracked']['p99_m'])} | {_f(s['tracked']['max_m'])} "
                     f"| {'yes' if ok else 'no'} |")
    return "\n".join(lines) + "\n"


def write_report(results: list[dict], out: Path) -> dict[str, Path]:
    """closed_loop.md (the tables) and closed_loop.csv (one row per cell)."""
    import pandas as pd

    out.mkdir(parents=True, exist_ok=True)
    paths = {"markdown": out / "closed_loop.md", "csv": out / "closed_loop.csv"}
    paths["markdown"].write_text(markdown_table(results))
    flat = [{k: v for k, v in r.items() if k not in ("raw", "tracked")}
            | {f"{k}_{m}": v for k in ("raw", "tracked") for m, v in error_stats(r[k]).items()}
            for r in results]
    pd.DataFrame(flat).to_csv(paths["csv"], index=False)
    return paths
