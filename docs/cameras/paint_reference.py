"""Reference offsets of the ego lines in real frames, measured on the paint at full resolution, to score a detector.

For each picture the detector's line only picks which paint to measure: along it, every second row of the
undistorted full-resolution frame between 6 and 20 m ahead is searched ±`SEARCH_PX` for the paint's bright
ridge; the ridge centres are back-projected to the ground with the calibration and straight lines y = a_i + b x with one
heading for both lines (lane lines are parallel; a dashed line borrows the solid one's heading) fitted to them
(robustly) give the reference c0 = a_i. A line with fewer than `MIN_ROWS` ridge rows has no
reference. `--check DIR` writes each frame with the ridge centres (green) and the detector's line (red) to be
looked at. Run: python docs/cameras/paint_reference.py CAL.toml 'GLOB' [--detector neural] [--check DIR]
"""

from __future__ import annotations

import argparse
import glob
from pathlib import Path

import cv2
import numpy as np

from hil.vehicle.camera_calibration import CameraCalibration, Rectifier
from testbed.lane_detection import CameraFrame
from testbed.perception.detectors.registry import make_detector
from vehicles.camera_rig import CameraRig
from vehicles.params import get_vehicle

SEARCH_PX, MIN_ROWS, RIDGE = 14, 12, 25.0
X_RANGE = (6.0, 20.0)


def ground_to_image(cal: CameraCalibration, xy: np.ndarray) -> np.ndarray:
    cam = (np.column_stack([xy, np.zeros(len(xy))]) - cal.mount) @ cal.vehicle_from_camera
    return (cam[:, :2] / cam[:, 2:]) @ cal.matrix[:2, :2].T + cal.matrix[:2, 2]


def image_to_ground(cal: CameraCalibration, uv: np.ndarray) -> np.ndarray:
    rays = np.column_stack([uv, np.ones(len(uv))]) @ np.linalg.inv(cal.matrix).T @ cal.vehicle_from_camera.T
    s = -cal.mount_height / rays[:, 2]
    return cal.mount[:2] + s[:, None] * rays[:, :2]


def ridge_centres(image: np.ndarray, seed: np.ndarray) -> np.ndarray:
    """Paint ridge centres (N, 2) near the seed pixels (rows)."""
    bright = 0.5 * (image[:, :, 0].astype(float) + image[:, :, 1].astype(float))
    found = []
    for u, v in seed:
        row, lo = round(v), round(u) - SEARCH_PX
        if row < 0 or row >= image.shape[0] or lo - 3 * SEARCH_PX < 0 or lo + 5 * SEARCH_PX >= image.shape[1]:
            continue
        window = bright[row, lo : lo + 2 * SEARCH_PX + 1]
        road = np.median(bright[row, lo - 3 * SEARCH_PX : lo + 5 * SEARCH_PX])
        if window.max() - road < RIDGE:
            continue
        weight = np.clip(window - road - 0.5 * (window.max() - road), 0, None)
        found.append((lo + float(np.sum(weight * np.arange(len(window))) / weight.sum()), row))
    return np.array(found).reshape(-1, 2)


def ridge_ground(cal: CameraCalibration, image: np.ndarray, coeffs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Ground points (N, 2) of the paint ridge along a detected line, and their pixels (N, 2)."""
    x = np.linspace(*X_RANGE, 400)
    seed = ground_to_image(cal, np.column_stack([x, np.polynomial.polynomial.polyval(x, coeffs)]))
    rows = np.unique(np.round(seed[:, 1] / 2) * 2)
    seed = np.column_stack([np.interp(rows, seed[::-1, 1], seed[::-1, 0]), rows])
    centres = ridge_centres(image, seed)
    return image_to_ground(cal, centres) if len(centres) else np.zeros((0, 2)), centres


def parallel_fit(points: list[np.ndarray]) -> list[float | None]:
    """Offsets a_i of lines y = a_i + b x sharing one heading b (lane lines are parallel), fitted by least squares
    to each line's ground points and refitted without those off by more than 0.15 m; None for a line with fewer
    than `MIN_ROWS` points."""
    used = [i for i, g in enumerate(points) if len(g) >= MIN_ROWS]
    keep = {i: np.ones(len(points[i]), bool) for i in used}
    sol = np.zeros(len(used) + 1)
    for _ in range(3):
        rows, rhs = [], []
        for k, i in enumerate(used):
            g = points[i][keep[i]]
            a = np.zeros((len(g), len(used) + 1))
            a[:, k], a[:, -1] = 1.0, g[:, 0]
            rows.append(a)
            rhs.append(g[:, 1])
        if not rows:
            break
        sol = np.linalg.lstsq(np.vstack(rows), np.concatenate(rhs), rcond=None)[0]
        for k, i in enumerate(used):
            keep[i] = np.abs(points[i][:, 1] - (sol[k] + sol[-1] * points[i][:, 0])) < 0.15
    out: list[float | None] = [None] * len(points)
    for k, i in enumerate(used):
        out[i] = float(sol[k]) if keep[i].sum() >= MIN_ROWS else None
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("calibration", type=Path)
    ap.add_argument("pattern")
    ap.add_argument("--detector", default="neural")
    ap.add_argument("--weights")
    ap.add_argument("--check", type=Path)
    args = ap.parse_args()
    cal = CameraCalibration.load(args.calibration)
    rig = CameraRig(get_vehicle("sedan").camera)
    rectify = Rectifier(cal, rig)
    det = make_detector(args.detector, track=None, rig=rig, params={"weights": args.weights} if args.weights else {})
    dist = np.array(cal.distortion or (0.0,) * 4)
    print("file,side,c0_detector,c0_reference,error_m")
    for path in sorted(glob.glob(args.pattern)):
        rgb = cv2.cvtColor(cv2.imread(path), cv2.COLOR_BGR2RGB)
        ld = det.detect(CameraFrame(0.0, rectify(rgb)))
        pinhole = cv2.undistort(rgb, cal.matrix, dist)
        check = cv2.cvtColor(pinhole, cv2.COLOR_RGB2BGR)
        lines = [("left", ld.left), ("right", ld.right)]
        found = [ridge_ground(cal, pinhole, c) if c is not None else (np.zeros((0, 2)), np.zeros((0, 2)))
                 for _, c in lines]
        refs = parallel_fit([g for g, _ in found])
        for (side, coeffs), ref, (_, centres) in zip(lines, refs, found, strict=True):
            if coeffs is None:
                print(f"{Path(path).name},{side},,,")
                continue
            err = "" if ref is None else f"{coeffs[0] - ref:.3f}"
            print(f"{Path(path).name},{side},{coeffs[0]:.3f},{'' if ref is None else f'{ref:.3f}'},{err}")
            x = np.linspace(*X_RANGE, 50)
            line = ground_to_image(cal, np.column_stack([x, np.polynomial.polynomial.polyval(x, coeffs)]))
            cv2.polylines(check, [line.round().astype(np.int32)], False, (0, 0, 255), 1)
            for u, v in centres:
                cv2.circle(check, (round(u), int(v)), 2, (0, 255, 0), -1)
        if args.check:
            args.check.mkdir(parents=True, exist_ok=True)
            cv2.imwrite(str(args.check / (Path(path).stem + ".png")), check)


if __name__ == "__main__":
    main()
