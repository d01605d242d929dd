"""Existence of the ego lines on frames without lane lines: the share of each kind of negative frame on which
both lines' existence stays under 0.5. Kinds (all seeded): uniform and Gaussian noise, black night frames (dark
with sensor noise), motion-blurred noise, non-road scenes (the top half of real frames: sky, trees, hills,
stretched to the detector's view), chessboards (the Advanced-Lane-Lines camera_cal pictures through that camera's
calibration).
Run: python docs/cameras/negatives.py DATA_REAL_DIR [--weights NAME]
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

ADVANCED = Path(__file__).with_name("udacity-advanced-lane-lines.toml")
LANELINES = Path(__file__).with_name("udacity-lanelines-p1.toml")


def negatives(real: Path, rig: CameraRig, n: int = 40, seed: int = 0) -> dict[str, list[np.ndarray]]:
    rng = np.random.default_rng(seed)
    shape = (rig.height, rig.width, 3)
    kinds: dict[str, list[np.ndarray]] = {
        "uniform noise": [rng.integers(0, 256, shape, dtype=np.uint8) for _ in range(n)],
        "gaussian noise": [np.clip(rng.normal(rng.uniform(60, 190), rng.uniform(10, 60), shape), 0, 255)
                           .astype(np.uint8) for _ in range(n)],
        "black night": [np.clip(rng.normal(rng.uniform(0, 12), 3.0, shape), 0, 255).astype(np.uint8)
                        for _ in range(n)],
    }
    blur = []
    for _ in range(n):
        kernel = np.zeros((1, 31), np.float32)
        kernel[0, :] = 1.0 / 31
        image = rng.integers(0, 256, shape, dtype=np.uint8)
        angle = rng.uniform(0, 180)
        rot = cv2.getRotationMatrix2D((15, 0), angle, 1.0)
        blur.append(cv2.filter2D(image, -1, cv2.warpAffine(kernel, rot, (31, 31)) if angle else kernel))
    kinds["motion blur"] = blur
    scenes = []
    for path in sorted(glob.glob(str(real / "**" / "*.jpg"), recursive=True)):
        if "camera_cal" in path or "examples" in path:
            continue
        bgr = cv2.imread(path)
        top = bgr[: bgr.shape[0] * 9 // 20]
        scenes.append(cv2.cvtColor(cv2.resize(top, (rig.width, rig.height), interpolation=cv2.INTER_AREA),
                                   cv2.COLOR_BGR2RGB))
    kinds["non-road scenes"] = scenes
    rectify = Rectifier(CameraCalibration.load(ADVANCED), rig)
    kinds["chessboards"] = [rectify(cv2.cvtColor(cv2.imread(p), cv2.COLOR_BGR2RGB))
                            for p in sorted(glob.glob(str(real / "Advanced-Lane-Lines" / "camera_cal" / "*.jpg")))
                            if cv2.imread(p).shape[:2] == (720, 1280)]
    return kinds


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("real", type=Path, help="folder holding the fetched Udacity repositories")
    ap.add_argument("--weights")
    args = ap.parse_args()
    rig = CameraRig(get_vehicle("sedan").camera)
    det = make_detector("neural", track=None, rig=rig, params={"weights": args.weights} if args.weights else {})
    total, passed = 0, 0
    for kind, frames in negatives(args.real, rig).items():
        probs = np.array([[ld.left_prob, ld.right_prob] for ld in (det.detect(CameraFrame(0.0, f)) for f in frames)])
        ok = (probs < 0.5).all(axis=1)
        total, passed = total + len(ok), passed + int(ok.sum())
        print(f"{kind}: {ok.sum()}/{len(ok)} with no line (existence max median {np.median(probs.max(axis=1)):.2f})")
    print(f"all: {passed}/{total} ({passed / total:.0%})")


if __name__ == "__main__":
    main()
