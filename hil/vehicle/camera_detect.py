"""`ld3 ld detect`: a lane detector on a camera alone, no GNSS or chassis. Each frame is fitted to the detector's
rig (by its calibration, else it must already be the rig's image), detected, and tracked with a constant-speed
odometry (no yaw rate); DIR/detections.csv has one row per frame, with an overlay of the detector's view and a
report with the deviation's plot.

The deviation from the lane centre (+ left) of a detection: −(c0_left + c0_right)/2 with both lines, one line's
|c0| against half the lane width last measured with both (3.5 m before any) with one, empty with none.
"""

from __future__ import annotations

import csv
import itertools
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hil.vehicle.camera_calibration import CameraCalibration, Rectifier, view_check
from hil.vehicle.camera_reader import OpenCvSource
from hil.vehicle.frame_stream import frame_stream
from testbed.errors import UserError
from testbed.lane_detection import CameraFrame, LaneDetection
from testbed.lane_tracker import NOMINAL_LANE_WIDTH, LaneTracker, TrackerParams
from vehicles.camera_rig import CameraRig

COLUMNS = ("t", "left_found", "right_found", "dev_m", "dev_raw_m", "lane_width_m", "left_existence",
           "right_existence", "left_c0_m", "right_c0_m")


@dataclass(frozen=True)
class DetectConfig:
    """What `ld3 ld detect` reads and writes: camera spec, calibration, detector (and its weights, None: default),
    frame rate of images, assumed speed (m/s) for the tracker, whether to track, the overlay kind, frame limit."""

    camera: str
    out: Path
    calibration: Path | None = None
    detector: str = "neural"
    weights: str | None = None
    fps: float = 20.0
    speed: float = 25.0
    tracking: bool = True
    overlay: str = "video"
    limit: int | None = None


CAMERA_ONLY_TRACKER = TrackerParams(measure_at=())
"""The tracker of a camera alone: fed the lines' coefficients. With no yaw rate, lines measured ahead would be carried
to the car along a heading the odometry does not turn (docs/decisions.md, "The lines measured ahead by default")."""


class LaneCentre:
    """Deviation from the lane centre (+ left) of successive detections, remembering the last lane width."""

    def __init__(self) -> None:
        self.width = NOMINAL_LANE_WIDTH

    def __call__(self, ld: LaneDetection) -> tuple[float | None, float | None]:
        """(deviation, lane width) of this detection; None where it cannot say."""
        left, right = ld.left, ld.right
        if left is not None and right is not None:
            self.width = float(left[0] - right[0])
            return -0.5 * float(left[0] + right[0]), self.width
        if left is not None:
            return 0.5 * self.width - abs(float(left[0])), None
        if right is not None:
            return abs(float(right[0])) - 0.5 * self.width, None
        return None, None


def frame_fitter(calibration: CameraCalibration | None, rig: CameraRig, shape: tuple[int, ...]):
    """A callable mapping the camera's frames to the rig's; refuses, in one line, what cannot be fitted."""
    if calibration is None:
        if shape[:2] != (rig.height, rig.width):
            raise UserError(f"camera frames are {shape[1]}x{shape[0]} but the detector reads the {rig.width}x"
                            f"{rig.height} view of its own rig: give --calibration CAL.toml (docs/camera.md)")
        return lambda image: image
    if (shape[1], shape[0]) != (calibration.width, calibration.height):
        raise UserError(f"camera frames are {shape[1]}x{shape[0]}, the calibration's {calibration.width}x"
                        f"{calibration.height}")
    return Rectifier(calibration, rig)


def source_fitter(source: OpenCvSource, calibration: CameraCalibration | None, rig: CameraRig):
    """`frame_fitter` for an opened camera or video from the frame size it reports, before a frame is read (the
    source is closed when refused); one that reports none is fitted on its first frame, in its reader."""
    import cv2  # the [camera] extra, already imported by the source

    shape = (int(source.capture.get(cv2.CAP_PROP_FRAME_HEIGHT)), int(source.capture.get(cv2.CAP_PROP_FRAME_WIDTH)))
    if min(shape) <= 0:
        return _FirstFrameFitter(calibration, rig)
    try:
        return frame_fitter(calibration, rig, shape)
    except UserError:
        source.close()
        raise


class _FirstFrameFitter:
    """`frame_fitter` built on the first frame it is given (a UserError there ends the camera's stream)."""

    def __init__(self, calibration: CameraCalibration | None, rig: CameraRig) -> None:
        self.calibration, self.rig = calibration, rig
        self.fit = None

    def __call__(self, image: np.ndarray) -> np.ndarray:
        if self.fit is None:
            self.fit = frame_fitter(self.calibration, self.rig, image.shape)
        return self.fit(image)


class Overlay:
    """The detector's view with the tracked lines and the deviation: `video` (DIR/overlay.mp4 at the frames' own
    rate, taken from the first two), `images` (DIR/overlay/NNNNNN.png) or `none`."""

    def __init__(self, kind: str, out: Path, rig: CameraRig, fps: float) -> None:
        self.kind, self.out, self.rig, self.fps = kind, out, rig, fps
        self.video = None
        self.first: tuple | None = None
        self.count = 0
        if kind == "images":
            (out / "overlay").mkdir(exist_ok=True)

    def add(self, frame: CameraFrame, ld: LaneDetection, signals) -> None:
        from testbed.eval.run.video import VideoWriter, draw_detection, draw_signals

        self.count += 1
        if self.kind == "images":
            import cv2  # the [camera] extra; imported where a picture is written

            picture = draw_signals(draw_detection(frame.image, ld, self.rig), signals)
            cv2.imwrite(str(self.out / "overlay" / f"{self.count - 1:06d}.png"), cv2.cvtColor(picture,
                                                                                             cv2.COLOR_RGB2BGR))
        elif self.kind == "video":
            if self.first is None:
                self.first = (frame, ld, signals)
                return
            if self.video is None:
                self.video = VideoWriter(self.rig, 1.0 / max(frame.t - self.first[0].t, 1e-3))
                self.video.add(*self.first)
            self.video.add(frame, ld, signals)

    def finish(self) -> None:
        """Write overlay.mp4 (a single frame plays at `fps`)."""
        from testbed.eval.run.video import VideoWriter

        if self.kind == "video" and self.video is None and self.first is not None:
            self.video = VideoWriter(self.rig, self.fps)
            self.video.add(*self.first)
        if self.video is not None:
            self.video.write(self.out / "overlay.mp4")

    def close(self) -> None:
        if self.video is not None:
            self.video.close()


def _number(value: float | None) -> str:
    return "" if value is None or not math.isfinite(value) else f"{value:.4f}"


def run_detect(config: DetectConfig, detector, rig: CameraRig) -> dict:
    """Run the pass; write detections.csv, the overlay and report.md (+ dev.png) under `config.out`; return the
    summary the report states."""
    from testbed.eval.run.video import FrameSignals

    calibration = CameraCalibration.load(config.calibration) if config.calibration else None
    warning = view_check(calibration, rig) if calibration else None
    frames = frame_stream(config.camera, config.fps)
    first = next(frames, None)  # what cannot be read or fitted is refused before anything is written
    if first is None:
        raise UserError(f"no frame came from {config.camera}")
    fit = frame_fitter(calibration, rig, first[1].shape)
    config.out.mkdir(parents=True, exist_ok=True)
    tracker = LaneTracker(CAMERA_ONLY_TRACKER) if config.tracking else None
    tracked_centre, raw_centre = LaneCentre(), LaneCentre()
    rows: list[dict] = []
    overlay = Overlay(config.overlay, config.out, rig, config.fps)
    try:
        for t, image in itertools.chain([first], frames):
            if config.limit is not None and len(rows) >= config.limit:
                break
            frame = CameraFrame(t, fit(image))
            raw = detector.detect(frame)
            ld = tracker.update(raw, config.speed, 0.0) if tracker is not None else raw
            dev, width = tracked_centre(ld)
            dev_raw, _ = raw_centre(raw)
            rows.append({"t": f"{t:.4f}", "left_found": int(raw.left is not None),
                         "right_found": int(raw.right is not None), "dev_m": _number(dev),
                         "dev_raw_m": _number(dev_raw), "lane_width_m": _number(width),
                         "left_existence": f"{raw.left_prob:.3f}", "right_existence": f"{raw.right_prob:.3f}",
                         "left_c0_m": _number(raw.left[0] if raw.left is not None else None),
                         "right_c0_m": _number(raw.right[0] if raw.right is not None else None)})
            overlay.add(frame, ld, FrameSignals(t, dev, None, None, None, "normal"))
        overlay.finish()
    finally:
        overlay.close()
        frames.close()
    with open(config.out / "detections.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, COLUMNS)
        writer.writeheader()
        writer.writerows(rows)
    summary = summarise(rows)
    summary["coverage"] = fit.coverage if isinstance(fit, Rectifier) else None
    summary["view_warning"] = warning
    write_report(config, summary, rows)
    return summary


def _series(rows: list[dict], key: str) -> np.ndarray:
    return np.array([float(r[key]) if r[key] != "" else np.nan for r in rows])


def summarise(rows: list[dict]) -> dict:
    """Frame counts and the steadiness of the deviations: p95 |change| between consecutive frames (m)."""
    both = sum(r["left_found"] and r["right_found"] for r in rows)
    out: dict = {"frames": len(rows), "both_lines": both, "both_share": both / len(rows)}
    for key in ("dev_m", "dev_raw_m"):
        step = np.abs(np.diff(_series(rows, key)))
        step = step[np.isfinite(step)]
        out[f"{key}_p95_step"] = float(np.percentile(step, 95)) if len(step) else None
    width = _series(rows, "lane_width_m")
    out["lane_width_median_m"] = float(np.nanmedian(width)) if np.isfinite(width).any() else None
    return out


def write_report(config: DetectConfig, summary: dict, rows: list[dict]) -> None:
    """report.md and dev.png: the deviations against time and the summary's figures."""
    from matplotlib.figure import Figure

    t = _series(rows, "t")
    fig = Figure(figsize=(8, 3.2))
    ax = fig.add_subplot()
    ax.plot(t, _series(rows, "dev_raw_m"), ".", ms=3, color="0.6", label="detector")
    ax.plot(t, _series(rows, "dev_m"), "-", lw=1.2, color="C0", label="tracked")
    ax.set_xlabel("t (s)")
    ax.set_ylabel("deviation from lane centre (m, + left)")
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    fig.savefig(config.out / "dev.png", dpi=110)

    def metres(value: float | None) -> str:
        return "-" if value is None else f"{value:.3f} m"

    lines = [f"# Lane detection on {config.camera}", "",
             f"Detector `{config.detector}`" + (f" (weights `{config.weights}`)" if config.weights else "")
             + f", calibration `{config.calibration or 'none (frames are the rig view)'}`"
             f", tracking {'on' if config.tracking else 'off'} (speed {config.speed:g} m/s).", ""]
    if summary["coverage"] is not None:
        lines += [f"The camera sees {summary['coverage']:.0%} of the road the detector reads.", ""]
    if summary["view_warning"]:
        lines += [f"**Warning:** {summary['view_warning']}.", ""]
    lines += ["| figure | value |", "|---|---|",
              f"| frames | {summary['frames']} |",
              f"| both lines found | {summary['both_lines']} ({summary['both_share']:.0%}) |",
              f"| p95 frame-to-frame change, tracked | {metres(summary['dev_m_p95_step'])} |",
              f"| p95 frame-to-frame change, detector | {metres(summary['dev_raw_m_p95_step'])} |",
              f"| median lane width | {metres(summary['lane_width_median_m'])} |", "",
              "![deviation](dev.png)", ""]
    (config.out / "report.md").write_text("\n".join(lines))
