"""A real camera's calibration file (TOML) and the rectification of its frames into the rig the lane detector
reads: undistorted, rotated to the rig's pitch and resampled to the rig's intrinsics.

```toml
[intrinsics]          # of the images the camera delivers
width = 1280
height = 720
fx = 1100.0
fy = 1100.0
cx = 639.5
cy = 359.5
distortion = [-0.31, 0.11, 0.0, 0.0, 0.0]   # OpenCV k1, k2, p1, p2[, k3]
[extrinsics]          # vehicle frame: metres ahead of the reference point, above the ground; degrees down
mount_x = 1.2
mount_height = 1.35
pitch_deg = 4.0
```
The rig keeps the detector's image size and vertical field of view; the mount comes from the file.
"""

from __future__ import annotations

import dataclasses
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from testbed.errors import UserError
from vehicles.camera_rig import CameraRig
from vehicles.params import CameraParams


@dataclass(frozen=True)
class CameraCalibration:
    """Intrinsics (px), distortion (OpenCV order) and mount (m, deg) of a real camera."""

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    distortion: tuple[float, ...]
    mount_x: float
    mount_height: float
    pitch_deg: float

    @classmethod
    def load(cls, path: Path) -> CameraCalibration:
        """Read the TOML file; a missing or malformed key is a one-line UserError naming it."""
        try:
            table = tomllib.loads(Path(path).read_text())
        except (OSError, tomllib.TOMLDecodeError) as exc:
            raise UserError(f"camera calibration {path}: {exc}") from None
        try:
            intr, extr = table["intrinsics"], table["extrinsics"]
            values: dict[str, Any] = {key: intr[key] for key in ("width", "height", "fx", "fy", "cx", "cy")}
            values["distortion"] = tuple(float(k) for k in intr.get("distortion", ()))
            values.update({key: float(extr[key]) for key in ("mount_x", "mount_height", "pitch_deg")})
        except (KeyError, TypeError, ValueError) as exc:
            raise UserError(f"camera calibration {path}: missing or bad entry {exc}") from None
        if len(values["distortion"]) not in (0, 4, 5, 8):
            raise UserError(f"camera calibration {path}: distortion takes 4, 5 or 8 OpenCV coefficients")
        return cls(**values)

    @property
    def matrix(self) -> np.ndarray:
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    def rig_params(self, detector: CameraParams) -> CameraParams:
        """The rig the rectified frames show: the detector's image size, field of view and pitch, this mount."""
        return dataclasses.replace(detector, mount_x=self.mount_x, mount_height=self.mount_height)


class Rectifier:
    """Maps a calibrated camera's frames (H × W × 3) into `rig`'s image: OpenCV remap tables built once."""

    def __init__(self, calibration: CameraCalibration, rig: CameraRig) -> None:
        import cv2

        self._cv2 = cv2
        camera = CameraRig(dataclasses.replace(rig.params, pitch_deg=calibration.pitch_deg))
        rotation = rig.T_vehicle_from_camera[:3, :3].T @ camera.T_vehicle_from_camera[:3, :3]
        self.size = (calibration.width, calibration.height)
        self.maps = cv2.initUndistortRectifyMap(calibration.matrix, np.array(calibration.distortion or (0.0,) * 4),
                                                rotation, rig.K, (rig.width, rig.height), cv2.CV_32FC1)

    def __call__(self, image: np.ndarray) -> np.ndarray:
        if (image.shape[1], image.shape[0]) != self.size:
            raise ValueError(f"camera frame is {image.shape[1]}x{image.shape[0]}, its calibration "
                             f"{self.size[0]}x{self.size[1]}")
        return self._cv2.remap(image, *self.maps, self._cv2.INTER_LINEAR)
