"""Closed-loop lane-detection accuracy per condition × preset (`ld3 ld closed-loop`).

Each cell drives a held-out track seed (`HELD_OUT_SEEDS`) of one preset in one condition for `duration`
seconds with the detector, MSF localization and no defense: control follows the MSF, so the detections never
steer the car and one drive serves both columns. Per control tick the error is |D_LD − phys_dev|, D_LD from
Alg. 3 as the loop computes it (map lane width at the MSF pose, last D held between frames and while no line is
valid): once of the tracked detections the loop used, once of the raw detections of the same frames.
A preset too short for the duration is driven slower, so that it lasts the duration.

With traffic (`traffic` cars, `testbed.perception.lab.traffic_drive`: a lead car `lead_gap` m ahead in the ego lane,
every car starting at rest with the ego) each frame also gets its occluded fraction
(`testbed.perception.training.occlusion`: the share of the ego lines' points in the detector's range that a car hides
from the camera), held per tick like D_LD, and the tables split the ticks into occluded (fraction > 0) and
clear. A neural detector given no weights reads the shipped `lanenet.pt`, with traffic as without.
"""

from __future__ import annotations

import contextlib
import math
import multiprocessing
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

import numpy as np
from tqdm import tqdm

from testbed.conditions import get_condition
from testbed.defense.ld_deviation import LdDeviation
from testbed.errors import UserError
from testbed.eval.run.runner import SimRun
from testbed.eval.run.scenario import END_MARGIN_M, Scenario, apply_settings, load_scenario
from testbed.lane_detection import CameraFrame, LaneDetection, LaneDetector
from testbed.params import ParamsError
from testbed.perception.detectors.registry import DETECTORS, make_detector
from testbed.perception.lab.traffic_drive import LEAD_GAP_M, traffic_drive
from testbed.perception.training.occlusion import FAR_M, NEAR_M, occluded_fraction
from testbed.perception.training.seeds import Cell, cells, check_cells
from testbed.presets import TRACKS
from tracks.map_api import OffMapError
from tracks.pose import Pose
from tracks.presets import load_track
from tracks.road import Track
from vehicles.camera_rig import CameraRig
from vehicles.params import get_vehicle

MEAN_TARGET_M = {"day": 0.05}
"""Mean |D_LD error| target with tracking per condition (`MEAN_TARGET_OTHER_M` elsewhere)."""
MEAN_TARGET_OTHER_M = 0.08
P99_TARGET_M = 0.20


class _RawTap(LaneDetector):
    """Passes a detector's output through, keeping each raw detection with the MSF pose of its tick and the
    frame's occluded fraction (`occlusion` of its true pose; None without traffic)."""

    def __init__(self, detector: LaneDetector) -> None:
        self.detector = detector
        self.reports_variance = detector.reports_variance
        self.reads_camera = detector.reads_camera
        self.name = getattr(detector, "name", type(detector).__name__)
        self.pose_now = lambda: None
        self.occlusion: Callable[[Pose], float | None] = lambda pose: None
        self.frames: list[tuple[LaneDetection, Pose | None, float | None]] = []

    def detect(self, frame: CameraFrame) -> LaneDetection:
        ld = self.detector.detect(frame)
        occluded = None if frame.true_pose is None else self.occlusion(frame.true_pose)
        self.frames.append((ld, self.pose_now(), occluded))
        return ld


def error_stats(err: np.ndarray) -> dict[str, float | None]:
    e = err[np.isfinite(err)]
    if not len(e):
        return {"mean_m": None, "p99_m": None, "max_m": None}
    return {"mean_m": float(e.mean()), "p99_m": float(np.percentile(e, 99)), "max_m": float(e.max())}


def drive_scenario(cell: Cell, detector: str, duration: float, seed: int = 0, traffic: int = 0,
                   lead_gap: float = LEAD_GAP_M, weights: str | None = None,
                   fit: str | None = None, settings: tuple[str, ...] = ()) -> tuple[Scenario, Track]:
    """The scenario of a cell's drive and its track (the detector's `weights` and anchor `fit` where given, then the
    `KEY=VALUE` `settings` as `ld3 run --set` applies them); a UserError where its road cannot hold the traffic."""
    base = load_scenario(cell.preset)
    spec = f"{cell.preset}@{cell.track_seed}"
    track = load_track(spec)
    room = track.length - base.start_s - END_MARGIN_M
    speed = min(base.speed, room / duration)
    table = None
    if traffic:
        fitted = traffic_drive(track, base.lane if base.lane is not None else track.ego_lane, base.start_s,
                               base.vehicle, speed, duration, traffic, lead_gap)
        speed, table = fitted.speed, fitted.traffic
    params = {k: v for k, v in (("weights", weights), ("fit", fit)) if v is not None}
    sc = base.with_overrides(track=spec, condition=cell.condition, duration=duration, speed=speed, seed=seed,
                             detector=detector, localization="msf", defense="none", name=f"ld-{cell.preset}",
                             traffic=table, **({"detector_params": params} if params else {}))
    return apply_settings(sc, list(settings)), track


def drive(cell: Cell, detector: str = "neural", duration: float = 30.0, seed: int = 0,
          existence_threshold: float = 0.5, traffic: int = 0, lead_gap: float = LEAD_GAP_M,
          weights: str | None = None, fit: str | None = None, settings: tuple[str, ...] = ()) -> dict:
    """Drive one cell (with `traffic` cars, see the module): what was driven, the per-tick errors (m) without
    (`raw`) and with (`tracked`) tracking, and the per-tick occluded fraction (`occluded`, NaN without traffic
    or before the first frame), and the detector and weights it read (`weights` None: its default); `weights`
    the detector's checkpoint (`detector.weights`, default its own), `fit` its
    anchor fit (`detector.fit`), `settings` further `KEY=VALUE` overrides of its scenario."""
    sc, track = drive_scenario(cell, detector, duration, seed, traffic, lead_gap, weights, fit, settings)
    spec, speed = sc.track, sc.speed
    rig = CameraRig(get_vehicle(sc.vehicle).camera)
    tap = _RawTap(make_detector(detector, track=track, rig=rig, rng=np.random.default_rng(seed),
                                params=sc.run_detector_params))
    sim = SimRun(sc, detector=tap, tracking=True)
    tap.pose_now = lambda: sim.loop.last_estimate.pose
    fleet = sim.parts.traffic
    if fleet is not None:
        car = get_vehicle(sc.traffic.vehicle)
        tap.occlusion = lambda pose: occluded_fraction(track, pose, rig, fleet.poses(),
                                                       (car.length, car.width, car.height))
    try:
        result = sim.run()
    finally:
        sim.close()
    rows = result.rows
    phys = np.array([np.nan if r.phys_dev is None else r.phys_dev for r in rows])
    tracked = np.array([np.nan if r.ld_dev is None else r.ld_dev for r in rows])
    raw, occluded = np.full(len(rows), np.nan), np.full(len(rows), np.nan)
    alg3, frames, last, hidden = LdDeviation(existence_threshold), iter(tap.frames), None, None
    for i, r in enumerate(rows):
        if r.ld_fresh:
            ld, pose, hidden = next(frames)
            with contextlib.suppress(OffMapError):
                last = alg3.update(ld, sim.parts.smap.lane_width(pose))
        raw[i] = np.nan if last is None else last
        occluded[i] = np.nan if hidden is None else hidden
    return {"preset": cell.preset, "condition": cell.condition, "track": spec, "speed_mps": round(speed, 2),
            "sim_time_s": round(len(rows) / sim.loop.rates.control_hz, 2), "frames": len(tap.frames),
            "traffic": traffic, "detector": detector, "weights": sc.run_detector_params.get("weights"),
            "fit": sc.run_detector_params.get("fit"),
            "consequence": result.summary["consequence"],
            "raw": np.abs(raw - phys), "tracked": np.abs(tracked - phys), "occluded": occluded}


def _one_thread() -> None:
    import torch

    torch.set_num_threads(1)


def run_closed_loop(presets: list[str], conditions: list[str], detector: str = "neural", duration: float = 30.0,
                    workers: int = 1, progress: bool = False, traffic: int = 0,
                    lead_gap: float | None = None, weights: str | None = None, check: bool = False,
                    fit: str | None = None, settings: tuple[str, ...] = ()) -> list[dict]:
    """Drive every cell (one torch thread each; `workers` processes at once; `traffic` cars, the lead
    `lead_gap` m ahead, default `LEAD_GAP_M`; the detector's checkpoint `weights`, default its own; on the check
    block's layouts with `check`; the anchor `fit`, default the detector's own; `settings`, `KEY=VALUE` overrides of
    every drive's scenario), results in cell order; a bad preset, condition, duration, traffic, weights, fit or
    setting is a UserError before any drive, and so is `detector.tracking`, which the matrix sets itself."""
    if not (math.isfinite(duration) and duration > 0):
        raise UserError(f"--duration must be a time > 0 s, got {duration}")
    if traffic < 0:
        raise UserError(f"--traffic must be a number of cars >= 0, got {traffic}")
    if lead_gap is not None and not traffic:
        raise UserError("--lead-gap places the lead car of --traffic: add --traffic N or drop it")
    if lead_gap is not None and not (math.isfinite(lead_gap) and 1.0 <= lead_gap <= 2000.0):
        raise UserError(f"--lead-gap must be a gap of 1-2000 m, got {lead_gap}")
    for preset in presets:
        TRACKS.get(preset)
    for condition in conditions:
        get_condition(condition)
    if weights is not None:
        try:
            DETECTORS.get(detector).settings({"weights": weights}, f"detector {detector}")
        except ParamsError as exc:
            raise UserError(f"--weights: {exc}") from None
    if fit is not None:
        try:
            DETECTORS.get(detector).settings({"fit": fit}, f"detector {detector}")
        except ParamsError as exc:
            raise UserError(f"--fit: {exc}") from None
    if any(item.partition("=")[0].strip() == "detector.tracking" for item in settings):
        raise UserError("--set detector.tracking: the closed-loop matrix measures every drive with and without "
                        "tracking itself; drop it")
    todo = (check_cells if check else cells)(presets, conditions)
    options = {"traffic": traffic, "lead_gap": LEAD_GAP_M if lead_gap is None else lead_gap, "weights": weights,
               "fit": fit, "settings": tuple(settings)}
    for cell in todo if traffic or settings else ():
        drive_scenario(cell, detector, duration, **options)
    bar = tqdm(total=len(todo), desc="closed loop", unit="drive", disable=not progress)
    if workers <= 1:
        _one_thread()
        out = []
        for cell in todo:
            bar.set_postfix_str(f"{cell.preset} {cell.condition}")
            out.append(drive(cell, detector, duration, **options))
            bar.update(1)
        return out
    results: dict[Cell, dict] = {}
    with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn"),
                             initializer=_one_thread) as pool:
        futures = {pool.submit(drive, cell, detector, duration, **options): cell for cell in todo}
        for future in as_completed(futures):
            results[futures[future]] = future.result()
            bar.update(1)
    return [results[cell] for cell in todo]


def _f(v: float | None) -> str:
    return "-" if v is None else f"{v:.3f}"


def mean_target(condition: str) -> float:
    return MEAN_TARGET_M.get(condition, MEAN_TARGET_OTHER_M)


def markdown_table(results: list[dict]) -> str:
    """The detector and weights driven, then per condition × preset and per condition (the ticks of its presets
    pooled), raw against tracked, with the targets."""
    read = sorted({f"{r['detector']} ({r['weights'] or 'its default weights'}"
                   f"{', fit ' + r['fit'] if r.get('fit') else ''})" for r in results if "detector" in r})
    lines = [f"Detector: {', '.join(read)}.", ""] if read else []
    lines += ["| condition | preset | track | s | raw mean | raw p99 | raw max | tracked mean | tracked p99 "
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
    if any(r.get("traffic") for r in results):
        lines += ["", *occlusion_table(results)]
    return "\n".join(lines) + "\n"


def _occluded_ticks(r: dict) -> np.ndarray:
    """Whether each tick of a drive was occluded (its last frame had a car hiding part of the ego lines)."""
    return np.nan_to_num(r["occluded"]) > 0.0


def _split(r: dict) -> tuple[np.ndarray, np.ndarray]:
    """The tracked errors of a drive's occluded ticks and of its clear ones."""
    occluded = _occluded_ticks(r)
    return r["tracked"][occluded], r["tracked"][~occluded]


def occlusion_table(results: list[dict]) -> list[str]:
    """With traffic: per cell the share of ticks occluded, their mean occluded fraction, and the tracked errors
    of the occluded and of the clear ticks, judged against the p99 target; then per condition, pooled."""
    lines = [f"With traffic: ticks whose last frame had a car hiding part of the ego lines within "
             f"{NEAR_M:g}-{FAR_M:g} m (occluded) and the others (clear); tracked |D_LD error|, p99 target "
             f"{P99_TARGET_M:.2f} m on every tick.", "",
             "| condition | preset | cars | speed (m/s) | consequence | occluded ticks | mean hidden share "
             "| occluded mean | occluded p99 | occluded max | clear mean | clear p99 | all p99 | meets p99 |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in results:
        occ, clear = (error_stats(e) for e in _split(r))
        share = _occluded_ticks(r)
        every = error_stats(r["tracked"])
        ok = every["p99_m"] is not None and every["p99_m"] <= P99_TARGET_M
        hidden = r["occluded"][share]
        lines.append(f"| {r['condition']} | {r['preset']} | {r['traffic']} | {r['speed_mps']:g} | {r['consequence']} "
                     f"| {share.mean():.2f} | {_f(float(hidden.mean()) if len(hidden) else None)} "
                     f"| {_f(occ['mean_m'])} | {_f(occ['p99_m'])} | {_f(occ['max_m'])} | {_f(clear['mean_m'])} "
                     f"| {_f(clear['p99_m'])} | {_f(every['p99_m'])} | {'yes' if ok else 'no'} |")
    lines += ["", "| condition | occluded ticks | occluded mean | occluded p99 | clear mean | clear p99 | all p99 "
              "| meets p99 |", "|---|---|---|---|---|---|---|---|"]
    for cond in dict.fromkeys(r["condition"] for r in results):
        group = [r for r in results if r["condition"] == cond]
        occ = error_stats(np.concatenate([_split(r)[0] for r in group]))
        clear = error_stats(np.concatenate([_split(r)[1] for r in group]))
        every = error_stats(np.concatenate([r["tracked"] for r in group]))
        share = np.concatenate([_occluded_ticks(r) for r in group]).mean()
        ok = every["p99_m"] is not None and every["p99_m"] <= P99_TARGET_M
        lines.append(f"| {cond} | {share:.2f} | {_f(occ['mean_m'])} | {_f(occ['p99_m'])} | {_f(clear['mean_m'])} "
                     f"| {_f(clear['p99_m'])} | {_f(every['p99_m'])} | {'yes' if ok else 'no'} |")
    return lines


def _occlusion_columns(r: dict) -> dict[str, float | None]:
    occluded, clear = _split(r)
    return ({"occluded_ticks": float(_occluded_ticks(r).mean())}
            | {f"occluded_{m}": v for m, v in error_stats(occluded).items()}
            | {f"clear_{m}": v for m, v in error_stats(clear).items()})


def write_report(results: list[dict], out: Path) -> dict[str, Path]:
    """closed_loop.md (the tables) and closed_loop.csv (one row per cell)."""
    import pandas as pd

    out.mkdir(parents=True, exist_ok=True)
    paths = {"markdown": out / "closed_loop.md", "csv": out / "closed_loop.csv"}
    paths["markdown"].write_text(markdown_table(results))
    flat = [{k: v for k, v in r.items() if k not in ("raw", "tracked", "occluded")}
            | {f"{k}_{m}": v for k in ("raw", "tracked") for m, v in error_stats(r[k]).items()}
            | (_occlusion_columns(r) if r.get("traffic") else {})
            for r in results]
    pd.DataFrame(flat).to_csv(paths["csv"], index=False)
    return paths
