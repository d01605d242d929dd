"""Evaluation of a lane detector on labelled held-out frames, per condition, the way LD3 uses it.

Per frame, D_LD comes from Alg. 3 (`LdDeviation`, fresh per frame, with the map lane width) and is
compared with the true physical deviation: mean |error|, p95, p99 (frames where no line is valid count
under `no_output`). Existence is scored per line: precision and recall of "present" and of "missing", its
errors also per band of the lines' visible fraction; where the dataset holds labels under other sensor draws
of the same render, the report says how often those flip (the labels' own repeatability).
The same statistics per track preset, per marking of the nearer line, and per occlusion: a frame is
`occluded` when traffic cars hide part of its ego lines within the detector's range (meta `occluded` > 0, the
share `testbed.perception.training.occlusion` computes from the frame's geometry when the dataset is rendered with
traffic), `clear` otherwise (frames without traffic included). Latency is `detect` wall time on one torch
thread (median, p99).
Writes ld_eval.json, ld_eval.md, a PNG grid of frames with detected (green) and true (red) lines drawn over
them, and a PNG of the error's cumulative distribution per condition.
"""

from __future__ import annotations

import json
import time
from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np
import torch

from testbed.defense.ld_deviation import LdDeviation
from testbed.lane_detection import CameraFrame, LaneDetection, LaneDetector
from testbed.perception.detectors.labels import VISIBLE_FRACTION
from testbed.perception.training.dataset import FrameSet
from testbed.perception.training.occlusion import FAR_M, NEAR_M
from tracks.pose import Pose
from vehicles.camera_rig import CameraRig


def _ratio(num: int, den: int) -> float | None:
    return num / den if den else None


def deviation_errors(detections: Sequence[LaneDetection], lane_width: np.ndarray, deviation: np.ndarray,
                     existence_threshold: float) -> np.ndarray:
    """|D_LD − true deviation| per frame (m), D_LD from Alg. 3 fresh per frame with the map lane width; NaN where
    no line is valid."""
    errs = np.full(len(detections), np.nan)
    for i, ld in enumerate(detections):
        d = LdDeviation(existence_threshold).update(ld, float(lane_width[i]))
        if d is not None:
            errs[i] = abs(d - float(deviation[i]))
    return errs


def existence_scores(said: np.ndarray, truth: np.ndarray) -> dict[str, float | int | None]:
    """Precision and recall of "present" and of "missing" for line calls `said` against labels `truth` (bools of
    one shape), and the number of lines labelled missing."""
    said, truth = np.asarray(said, bool), np.asarray(truth, bool)
    tp, fp = int((said & truth).sum()), int((said & ~truth).sum())
    fn, tn = int((~said & truth).sum()), int((~said & ~truth).sum())
    return {"present_precision": _ratio(tp, tp + fp), "present_recall": _ratio(tp, tp + fn),
            "missing_precision": _ratio(tn, tn + fn), "missing_recall": _ratio(tn, tn + fp),
            "missing_lines": tn + fp}


def said_present(detections: Sequence[LaneDetection], existence_threshold: float) -> np.ndarray:
    """(N, 2) bools: whether each frame's detection outputs its left and right line at the threshold."""
    return np.array([[ld.left is not None and ld.left_prob >= existence_threshold,
                      ld.right is not None and ld.right_prob >= existence_threshold] for ld in detections],
                    dtype=bool).reshape(-1, 2)


def existence_labels(frames: FrameSet) -> np.ndarray:
    """(N, 2) bools: the frames' left and right existence labels."""
    return np.stack([frames.left_exists, frames.right_exists], axis=1).astype(bool)


def score(said: np.ndarray, frames: FrameSet, idx: np.ndarray, errors: np.ndarray) -> dict[str, float | int | None]:
    """Deviation error statistics (from `errors`) and existence precision/recall (line calls `said`, (N, 2))
    over the frames `idx`."""
    e = errors[idx]
    e = e[np.isfinite(e)]
    return {
        "frames": len(idx), "no_output": int(len(idx) - len(e)),
        "mean_abs_err_m": float(e.mean()) if len(e) else None,
        "p95_err_m": float(np.percentile(e, 95)) if len(e) else None,
        "p99_err_m": float(np.percentile(e, 99)) if len(e) else None,
        **existence_scores(said[idx], existence_labels(frames)[idx]),
    }


VISIBLE_BANDS = (0.0, 0.10, VISIBLE_FRACTION, 0.25, 0.45, 0.80)  # lower edges of the visible-fraction bands


def errors_by_visibility(said: np.ndarray, frames: FrameSet) -> list[dict] | None:
    """Existence errors per band of the lines' visible fraction (meta `visible`; None for datasets rendered
    before it was recorded): lines, how many labelled present, how many called wrongly each way."""
    if not frames.meta or any("visible" not in m for m in frames.meta):
        return None
    visible = np.array([[np.nan if v is None else v for v in m["visible"]] for m in frames.meta], dtype=float)
    truth = existence_labels(frames)
    band = np.where(np.isnan(visible), -1, np.searchsorted(VISIBLE_BANDS, np.nan_to_num(visible), "right") - 1)
    edges = [*VISIBLE_BANDS, 1.0]
    rows = []
    for b in range(-1, len(VISIBLE_BANDS)):
        m = band == b
        name = "not judged" if b < 0 else f"{edges[b]:.2f}-{edges[b + 1]:.2f}"
        rows.append({"visible_fraction": name, "lines": int(m.sum()), "labelled_present": int(truth[m].sum()),
                     "said_present_labelled_missing": int((said & ~truth)[m].sum()),
                     "said_missing_labelled_present": int((~said & truth)[m].sum())})
    return rows


def label_repeatability(frames: FrameSet) -> dict | None:
    """How repeatable the existence labels are under other sensor draws of the same render (meta
    `redrawn_exists`; None where the dataset was rendered without them): the share of labels each redraw flips,
    overall and per condition, and the existence scores the redrawn labels themselves get against the labels
    (how far the label moves when only the sensor draw changes)."""
    if not frames.meta or any("redrawn_exists" not in m for m in frames.meta):
        return None
    truth = existence_labels(frames)
    redrawn = np.array([m["redrawn_exists"] for m in frames.meta], dtype=bool)  # (N, K, 2)
    flips = redrawn != truth[:, None, :]
    cond = np.asarray([m.get("condition", "?") for m in frames.meta])
    return {"draws": int(redrawn.shape[1]), "lines": int(truth.size), "flip_rate": float(flips.mean()),
            "lines_flipped_in_any_draw": int(flips.any(axis=1).sum()),
            "flip_rate_per_condition": {c: float(flips[cond == c].mean()) for c in sorted(set(cond.tolist()))},
            "redrawn_labels_scored": existence_scores(redrawn, np.broadcast_to(truth[:, None, :], redrawn.shape))}


def near_line_kinds(frames: FrameSet) -> list[str]:
    """Per frame, the marking kind of the true line nearer the car (the one Alg. 3 should use: left when the
    deviation is >= 0); '?' for datasets rendered before the kinds were recorded."""
    return [m.get("left_kind" if d >= 0.0 else "right_kind", "?") for m, d in zip(frames.meta, frames.deviation,
                                                                                   strict=True)]


def occlusion_groups(frames: FrameSet) -> list[str]:
    """Per frame, 'occluded' where traffic hides part of its ego lines (meta `occluded` > 0), else 'clear'."""
    return ["occluded" if (m.get("occluded") or 0.0) > 0.0 else "clear" for m in frames.meta]


def evaluate(detector: LaneDetector, frames: FrameSet, existence_threshold: float = 0.5,
             progress: bool = False) -> tuple[dict, list[LaneDetection]]:
    """Detect on every frame (one torch thread) and score per condition, per track preset and overall; the
    report keeps the per-frame errors (`frame_errors_m`, null where no output) for plots."""
    from tqdm import tqdm

    torch.set_num_threads(1)
    detections, latency = [], []
    for i in tqdm(range(len(frames)), desc="evaluating", unit="frame", disable=not progress):
        pose = Pose(*frames.meta[i]["pose"])
        frame = CameraFrame(float(i), frames.images[i], pose)
        t0 = time.perf_counter()
        detections.append(detector.detect(frame))
        latency.append(time.perf_counter() - t0)
    errors = deviation_errors(detections, frames.lane_width, frames.deviation, existence_threshold)
    said = said_present(detections, existence_threshold)

    def by(values: list[str]) -> dict[str, dict]:
        arr = np.asarray(values)
        return {v: score(said, frames, np.flatnonzero(arr == v), errors) for v in sorted(set(values))}

    report: dict = {"detector": type(detector).__name__, "existence_threshold": existence_threshold,
                    "per_condition": by([m.get("condition", "?") for m in frames.meta]),
                    "per_preset": by([m.get("preset", "?") for m in frames.meta]),
                    "per_near_line": by(near_line_kinds(frames)),
                    "per_occlusion": by(occlusion_groups(frames)),
                    "overall": score(said, frames, np.arange(len(frames)), errors),
                    "existence_by_visible_fraction": errors_by_visibility(said, frames),
                    "label_repeatability": label_repeatability(frames),
                    "frame_errors_m": [None if not np.isfinite(e) else round(float(e), 5) for e in errors]}
    lat = np.asarray(latency) * 1e3
    report["latency_ms"] = {"median": float(np.median(lat)), "p99": float(np.percentile(lat, 99)),
                            "threads": 1}
    return report, detections


def markdown_table(reports: list[dict]) -> str:
    def f(v: float | None, fmt: str = ".3f") -> str:
        return "-" if v is None else format(v, fmt)

    def rows(group: str, header: str) -> list[str]:
        lines = [f"| detector | {header} | frames | mean abs err (m) | p95 (m) | p99 (m) | missing P | missing R "
                 "| present P | present R | no output |", "|---|---|---|---|---|---|---|---|---|---|---|"]
        for rep in reports:
            for name, s in [*rep[group].items(), ("all", rep["overall"])]:
                lines.append(f"| {rep['detector']} | {name} | {s['frames']} | {f(s['mean_abs_err_m'])} "
                             f"| {f(s['p95_err_m'])} | {f(s['p99_err_m'])} | {f(s['missing_precision'])} "
                             f"| {f(s['missing_recall'])} | {f(s['present_precision'])} "
                             f"| {f(s['present_recall'])} | {s['no_output']} |")
        return lines

    lines = [*rows("per_condition", "condition"), "", "Per track preset:", "", *rows("per_preset", "preset"), "",
             "Per marking of the nearer true line (the one Alg. 3 uses):", "", *rows("per_near_line", "nearer line"),
             "", f"Per occlusion of the ego lines by traffic (occluded: a car hides part of them within "
                 f"{NEAR_M:g}-{FAR_M:g} m):", "",
             *rows("per_occlusion", "occlusion"), ""]
    for rep in reports:
        if rep.get("existence_by_visible_fraction"):
            lines += [f"{rep['detector']} existence errors by the lines' visible fraction (label: present from "
                      f"{VISIBLE_FRACTION}):", "", "| visible fraction | lines | labelled present | said present, "
                      "labelled missing | said missing, labelled present |", "|---|---|---|---|---|"]
            lines += [f"| {r['visible_fraction']} | {r['lines']} | {r['labelled_present']} "
                      f"| {r['said_present_labelled_missing']} | {r['said_missing_labelled_present']} |"
                      for r in rep["existence_by_visible_fraction"]]
            lines.append("")
    rep_noise = next((r["label_repeatability"] for r in reports if r.get("label_repeatability")), None)
    if rep_noise is not None:
        sc = rep_noise["redrawn_labels_scored"]
        per = ", ".join(f"{c} {v:.3f}" for c, v in rep_noise["flip_rate_per_condition"].items())
        lines += [f"Label repeatability ({rep_noise['draws']} other sensor draws of each render): "
                  f"{rep_noise['flip_rate']:.3f} of labels flip per draw ({per}); "
                  f"{rep_noise['lines_flipped_in_any_draw']} of {rep_noise['lines']} lines flip in some draw. "
                  f"The redrawn labels scored against the labels: missing P {f(sc['missing_precision'])}, "
                  f"missing R {f(sc['missing_recall'])}, present P {f(sc['present_precision'])}, "
                  f"present R {f(sc['present_recall'])}.", ""]
    for rep in reports:
        lat = rep["latency_ms"]
        lines.append(f"{rep['detector']} latency (1 thread): median {lat['median']:.2f} ms, "
                     f"p99 {lat['p99']:.2f} ms")
    return "\n".join(lines) + "\n"


def error_cdf(reports: list[dict], frames: FrameSet, path: Path, target_m: float = 0.20) -> Path:
    """PNG: cumulative distribution of |D_LD error| per condition, one panel per detector, the p99 target
    dashed."""
    from matplotlib.figure import Figure

    cond = np.asarray([m["condition"] for m in frames.meta])
    fig = Figure(figsize=(5.5 * len(reports), 3.8))
    axes = fig.subplots(1, len(reports), squeeze=False)
    for ax, rep in zip(axes[0], reports, strict=True):
        errors = np.asarray([np.nan if e is None else e for e in rep["frame_errors_m"]], dtype=float)
        for c in sorted(set(cond.tolist())):
            e = np.sort(errors[(cond == c) & np.isfinite(errors)])
            if len(e):
                ax.plot(e, np.arange(1, len(e) + 1) / len(e), label=c)
        ax.axvline(target_m, color="k", ls="--", lw=0.8)
        ax.axhline(0.99, color="k", ls=":", lw=0.8)
        ax.set_xscale("log")
        ax.set_xlim(1e-3, 2.0)
        ax.set_ylim(0.5, 1.0)
        ax.set_xlabel("|D_LD error| (m)")
        ax.set_ylabel("fraction of frames")
        ax.set_title(rep["detector"], fontsize=10)
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    return path


def _draw(img: np.ndarray, rig: CameraRig, coeffs: np.ndarray | None, colour: tuple[int, int, int]) -> None:
    if coeffs is None:
        return
    x = np.linspace(4.0, 40.0, 40)
    uv = rig.ground_to_pixel(np.column_stack([x, np.polynomial.polynomial.polyval(x, coeffs)]))
    pts = uv[np.isfinite(uv).all(axis=1)].round().astype(np.int32)
    if len(pts) > 1:
        cv2.polylines(img, [pts], False, colour, 1, cv2.LINE_AA)


def frame_grid(frames: FrameSet, detections: list[LaneDetection], rig: CameraRig, path: Path,
               per_condition: int = 2) -> Path:
    """PNG grid: `per_condition` frames of each condition, truth in red, detection in green."""
    cond = [m["condition"] for m in frames.meta]
    tiles = []
    for c in sorted(set(cond)):
        for i in [j for j, v in enumerate(cond) if v == c][:per_condition]:
            img = frames.images[i].copy()
            _draw(img, rig, frames.left[i] if frames.left_exists[i] else None, (255, 0, 0))
            _draw(img, rig, frames.right[i] if frames.right_exists[i] else None, (255, 0, 0))
            _draw(img, rig, detections[i].left, (0, 255, 0))
            _draw(img, rig, detections[i].right, (0, 255, 0))
            cv2.putText(img, c, (4, 14), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (255, 255, 255), 1, cv2.LINE_AA)
            tiles.append(img)
    cols = 4
    while len(tiles) % cols:
        tiles.append(np.zeros_like(tiles[0]))
    grid = np.vstack([np.hstack(tiles[r : r + cols]) for r in range(0, len(tiles), cols)])
    cv2.imwrite(str(path), np.ascontiguousarray(grid[:, :, ::-1]))
    return path


def write_report(reports: list[dict], grid_source: tuple[FrameSet, list[LaneDetection], CameraRig] | None,
                 out: Path) -> dict[str, Path]:
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    paths = {"json": out / "ld_eval.json", "markdown": out / "ld_eval.md"}
    paths["json"].write_text(json.dumps(reports, indent=1))
    paths["markdown"].write_text(markdown_table(reports))
    if grid_source is not None:
        paths["grid"] = frame_grid(*grid_source, out / "ld_eval_grid.png")
        paths["cdf"] = error_cdf(reports, grid_source[0], out / "ld_eval_cdf.png")
    return paths
