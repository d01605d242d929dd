"""`ld3 ld eval --labels tusimple:PATH`: a lane detector scored on labelled real frames with the benchmark's own metric.

Each labelled frame is fitted to the detector's rig through the camera's calibration (as `ld3 ld detect` does), its
ego lines (left, right) are projected back into the original frame at the label's rows and scored against the two
labelled ego lanes (hil.vehicle.tusimple_metric): the benchmark's metric on the ego-lane subset, since the detectors
read only the ego lines. The lines are drawn at every labelled row whose ground the camera sees (extrapolated past
the detector's 30 m); the same metric on the rows 5-30 m ahead (the ground the detector reads) is given beside it.
DIR/eval.csv has one row per frame and detector; DIR/report.md the totals and pictures of the worst frames.
"""

from __future__ import annotations

import csv
import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hil.vehicle.camera_calibration import DETECTOR_WINDOW, CameraCalibration, Rectifier, normal_bounds, view_check
from hil.vehicle.tusimple_labels import LabelledFrame, parse_labels, read_tusimple
from hil.vehicle.tusimple_metric import ABSENT, BENCHMARK_WIDTH, PIXEL_THRESHOLD, FrameScore, bench, ego_lanes
from testbed.errors import UserError
from testbed.lane_detection import CameraFrame, LaneDetection
from vehicles.camera_rig import CameraRig

NEAR_M, FAR_M = 0.5, 200.0
"""Ground (m ahead of the reference point) over which a detected line is drawn into the frame."""
ASPECT_TOLERANCE = 0.005
WORST_PICTURES = 2
COLUMNS = ("detector", "raw_file", "left_found", "right_found", "left_labelled", "right_labelled", "accuracy", "fp",
           "fn", "left_accuracy", "right_accuracy", "accuracy_5_30", "fp_5_30", "fn_5_30")


def fitted_calibration(calibration: CameraCalibration, width: int, height: int) -> CameraCalibration:
    """The calibration for frames of `width` × `height`: itself, or its intrinsics scaled for a resized copy of the
    camera's frames (the same shape); a one-line UserError for frames of another shape."""
    if (width, height) == (calibration.width, calibration.height):
        return calibration
    sx, sy = width / calibration.width, height / calibration.height
    if abs(sx / sy - 1.0) > ASPECT_TOLERANCE:
        raise UserError(f"labelled frames are {width}x{height}, the calibration's {calibration.width}x"
                        f"{calibration.height}: not a resized copy of its camera's frames")
    return dataclasses.replace(calibration, width=width, height=height, fx=calibration.fx * sx,
                               fy=calibration.fy * sy, cx=(calibration.cx + 0.5) * sx - 0.5,
                               cy=(calibration.cy + 0.5) * sy - 0.5)


def project_line(calibration: CameraCalibration, coeffs: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """x (px) of a detected line y(x) (vehicle frame) at each image row of `rows`, drawn from `NEAR_M` to `FAR_M`
    ahead; `ABSENT` at rows it does not reach or where it leaves the image."""
    import cv2

    out = np.full(len(rows), float(ABSENT))
    x = 1.0 / np.linspace(1.0 / NEAR_M, 1.0 / FAR_M, 4000)
    ground = np.column_stack([x, np.polynomial.polynomial.polyval(x, coeffs), np.zeros_like(x)])
    cam = (ground - calibration.mount) @ calibration.vehicle_from_camera
    cam = cam[cam[:, 2] > 1e-6]
    normal = cam[:, :2] / cam[:, 2:]
    lo, hi = normal_bounds(calibration)
    normal = normal[(normal >= lo).all(axis=1) & (normal <= hi).all(axis=1)]
    if len(normal) < 2:
        return out
    dist = np.array(calibration.distortion or (0.0,) * 4)
    uv = cv2.projectPoints(np.column_stack([normal, np.ones(len(normal))]), np.zeros(3), np.zeros(3),
                           calibration.matrix, dist)[0][:, 0, :]
    order = np.argsort(uv[:, 1])
    v, u = uv[order, 1], uv[order, 0]
    inside = (rows >= v[0]) & (rows <= v[-1])
    out[inside] = np.interp(rows[inside], v, u)
    out[(out < 0) | (out > calibration.width - 1)] = ABSENT
    return out


def row_distance(calibration: CameraCalibration, rows: np.ndarray) -> np.ndarray:
    """Metres ahead of the reference point of the ground each image row shows at the principal point's column
    (inf at and above the horizon)."""
    import cv2

    pixels = np.column_stack([np.full(len(rows), calibration.cx), rows])[:, None, :]
    normal = cv2.undistortPoints(pixels, calibration.matrix, np.array(calibration.distortion or (0.0,) * 4))[:, 0]
    rays = np.column_stack([normal, np.ones(len(rows))]) @ calibration.vehicle_from_camera.T
    out = np.full(len(rows), np.inf)
    down = rays[:, 2] < -1e-9
    out[down] = calibration.mount_x - calibration.mount_height * rays[down, 0] / rays[down, 2]
    return out


@dataclass(frozen=True)
class FrameResult:
    """A detector's lines on one labelled frame (x px at the label's rows) and their scores."""

    frame: LabelledFrame
    found: tuple[bool, bool]
    predicted: tuple[np.ndarray, ...]
    ego: tuple[int | None, int | None]
    score: FrameScore
    score_near: FrameScore
    side_accuracy: tuple[float | None, float | None]
    width: int


def score_frame(frame: LabelledFrame, ld: LaneDetection, calibration: CameraCalibration) -> FrameResult:
    """The benchmark's metric of the detection's ego lines against the frame's labelled ego lanes, on all labelled
    rows and on the rows showing ground 5-30 m ahead."""
    width, height = calibration.width, calibration.height
    ego = ego_lanes(list(frame.lanes), frame.rows, width, height)
    gt = [frame.lanes[i] for i in ego if i is not None]
    predicted = tuple(project_line(calibration, c, frame.rows) for c in (ld.left, ld.right) if c is not None)
    score = bench(list(predicted), gt, frame.rows, width)
    (x0, x1), _ = DETECTOR_WINDOW
    ahead = row_distance(calibration, frame.rows)
    near = (ahead >= x0) & (ahead <= x1)
    score_near = bench([p[near] for p in predicted], [g[near] for g in gt], frame.rows[near], width)
    accuracies = iter(score.lane_accuracy)
    left, right = (next(accuracies) if i is not None else None for i in ego)
    return FrameResult(frame, (ld.left is not None, ld.right is not None), predicted, ego, score, score_near,
                       (left, right), width)


def evaluate(frames: list[LabelledFrame], detectors: dict, calibration: CameraCalibration, rig: CameraRig,
             progress: bool = False) -> dict[str, list[FrameResult]]:
    """Fit each frame to the rig through its calibration (scaled to the frame's size) once, then detect and score
    it with every detector of `detectors` (name -> detector)."""
    import cv2

    fitters: dict[tuple[int, int], tuple[CameraCalibration, Rectifier]] = {}
    results: dict[str, list[FrameResult]] = {name: [] for name in detectors}
    for k, frame in enumerate(frames):
        bgr = cv2.imread(str(frame.image), cv2.IMREAD_COLOR)
        if bgr is None:
            raise UserError(f"cannot read the labelled frame {frame.image}")
        size = (bgr.shape[1], bgr.shape[0])
        if size not in fitters:
            cal = fitted_calibration(calibration, *size)
            fitters[size] = (cal, Rectifier(cal, rig))
        cal, rectify = fitters[size]
        view = rectify(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB))
        for name, detector in detectors.items():
            results[name].append(score_frame(frame, detector.detect(CameraFrame(float(k), view)), cal))
        if progress:
            print(f"\r{k + 1}/{len(frames)} frames", end="", flush=True)
    if progress:
        print()
    return results


def _number(value: float | None) -> str:
    return "" if value is None else f"{value:.4f}"


def csv_rows(name: str, results: list[FrameResult]) -> list[dict]:
    return [{"detector": name, "raw_file": r.frame.raw_file, "left_found": int(r.found[0]),
             "right_found": int(r.found[1]), "left_labelled": int(r.ego[0] is not None),
             "right_labelled": int(r.ego[1] is not None), "accuracy": _number(r.score.accuracy),
             "fp": _number(r.score.fp), "fn": _number(r.score.fn), "left_accuracy": _number(r.side_accuracy[0]),
             "right_accuracy": _number(r.side_accuracy[1]), "accuracy_5_30": _number(r.score_near.accuracy),
             "fp_5_30": _number(r.score_near.fp), "fn_5_30": _number(r.score_near.fn)} for r in results]


def totals(results: list[FrameResult]) -> dict:
    """The benchmark's totals (means over frames of accuracy, FP and FN), on all rows and on 5-30 m."""
    out: dict = {"frames": len(results), "both_found": sum(all(r.found) for r in results),
                 "ego_labelled": sum(i is not None for r in results for i in r.ego)}
    for key, pick in (("", lambda r: r.score), ("_5_30", lambda r: r.score_near)):
        for metric in ("accuracy", "fp", "fn"):
            out[metric + key] = float(np.mean([getattr(pick(r), metric) for r in results]))
    return out


def draw(result: FrameResult, path: Path) -> None:
    """The original frame with its labelled lanes (grey; ego lanes green) and the detector's lines (red) at the
    label's rows."""
    import cv2

    image = cv2.imread(str(result.frame.image), cv2.IMREAD_COLOR)
    radius = max(2, round(image.shape[1] / 320))
    for i, lane in enumerate(result.frame.lanes):
        colour = (0, 200, 0) if i in result.ego else (160, 160, 160)
        for x, y in zip(lane, result.frame.rows, strict=True):
            if x >= 0:
                cv2.circle(image, (round(x), round(y)), radius, colour, -1, cv2.LINE_AA)
    for lane in result.predicted:
        for x, y in zip(lane, result.frame.rows, strict=True):
            if x >= 0:
                cv2.circle(image, (round(x), round(y)), max(1, radius - 1), (0, 0, 255), -1, cv2.LINE_AA)
    s = result.score
    text = f"{result.frame.raw_file}  acc {s.accuracy:.2f}  FP {s.fp:.2f}  FN {s.fn:.2f}"
    cv2.putText(image, text, (6, 6 + 4 * radius), cv2.FONT_HERSHEY_SIMPLEX, 0.3 * radius, (255, 255, 255), 1,
                cv2.LINE_AA)
    cv2.imwrite(str(path), image)


@dataclass(frozen=True)
class LabelledEvalConfig:
    """What `ld3 ld eval --labels` reads and writes."""

    labels: str
    calibration: Path
    detectors: tuple[str, ...]
    weights: str | None = None
    limit: int | None = None


def load_inputs(config: LabelledEvalConfig) -> tuple[list[LabelledFrame], CameraCalibration]:
    """The labelled frames (at most `limit`) and the calibration; one-line UserErrors for what cannot be read."""
    _, path = parse_labels(config.labels)
    frames = read_tusimple(path)[: config.limit]
    calibration = CameraCalibration.load(config.calibration)
    fitted_calibration(calibration, *_size(frames[0].image))  # refused before anything is written
    return frames, calibration


def _size(image: Path) -> tuple[int, int]:
    import cv2

    picture = cv2.imread(str(image), cv2.IMREAD_UNCHANGED)
    if picture is None:
        raise UserError(f"cannot read the labelled frame {image}")
    return picture.shape[1], picture.shape[0]


def run_labelled_eval(config: LabelledEvalConfig, frames: list[LabelledFrame], calibration: CameraCalibration,
                      make_detector, rig: CameraRig, out: Path, progress: bool = False) -> dict[str, dict]:
    """Score each detector (`make_detector(name)`) on the labelled frames; write eval.csv, report.md and the
    worst frames' pictures under `out`; return each detector's totals."""
    warning = view_check(calibration, rig)
    rows, summary, pictures = [], {}, {}
    widths: set[int] = set()
    scored = evaluate(frames, {name: make_detector(name) for name in config.detectors}, calibration, rig, progress)
    for name, results in scored.items():
        widths |= {r.width for r in results}
        rows += csv_rows(name, results)
        summary[name] = totals(results)
        worst = sorted(range(len(results)), key=lambda k: (results[k].score.accuracy, k))[:WORST_PICTURES]
        pictures[name] = []
        for rank, k in enumerate(worst):
            picture = f"worst_{name}_{rank}.png"
            draw(results[k], out / picture)
            pictures[name].append(picture)
    with open(out / "eval.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, COLUMNS)
        writer.writeheader()
        writer.writerows(rows)
    write_report(config, summary, pictures, warning, widths.pop() if len(widths) == 1 else None, out)
    return summary


def write_report(config: LabelledEvalConfig, summary: dict[str, dict], pictures: dict[str, list[str]],
                 warning: str | None, width: int | None, out: Path) -> None:
    threshold = "" if width is None else \
        f" ({PIXEL_THRESHOLD * width / BENCHMARK_WIDTH:.1f} px on these {width}-px frames)"
    lines = [f"# Lane detectors on labelled frames: {config.labels}", "",
             f"Calibration `{config.calibration}`" + (f", weights `{config.weights}`" if config.weights else "") + ".",
             "", "The TuSimple benchmark's metric (a point right within 20 px at 1280 wide" + threshold
             + ", widened by the lane's angle; a lane matched at 0.85) on the **ego-lane subset**: the detectors "
             "read only the ego lines, so they are scored against the two labelled lanes nearest the bottom centre. "
             "Lines are drawn at every labelled row (extrapolated past the detector's 30 m); `5-30 m` scores only "
             "the rows showing ground 5-30 m ahead.", ""]
    if warning:
        lines += [f"**Warning:** {warning}.", ""]
    lines += ["| detector | frames | both lines found | accuracy | FP | FN | accuracy 5-30 m | FP 5-30 m | FN 5-30 m |",
              "|---|---|---|---|---|---|---|---|---|"]
    for name, s in summary.items():
        lines.append(f"| {name} | {s['frames']} | {s['both_found']} | {s['accuracy']:.3f} | {s['fp']:.3f} | "
                     f"{s['fn']:.3f} | {s['accuracy_5_30']:.3f} | {s['fp_5_30']:.3f} | {s['fn_5_30']:.3f} |")
    lines += ["", "Worst frames (labelled lanes grey, ego lanes green, the detector's lines red):", ""]
    for name, names in pictures.items():
        lines += [f"![{name} {p}]({p})" for p in names]
    (out / "report.md").write_text("\n".join(lines) + "\n")
