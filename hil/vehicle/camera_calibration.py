"""A real camera's calibration file (TOML) and the rectification of its frames into the rig the lane detector
reads: the road plane the camera sees is redrawn as the detector's rig would see it from its own mount.

```toml
[intrinsics]          # of the images the camera delivers
width = 1280
height = 720
fx = 1100.0
fy = 1100.0
cx = 639.5
cy = 359.5
distortion = [-0.31, 0.11, 0.0, 0.0, 0.0]   # OpenCV k1, k2, p1, p2[, k3]
[extrinsics]          # vehicle frame: metres ahead of the reference point, to its left, above the ground
mount_x = 1.2
mount_y = 0.0         # optional, default 0
mount_height = 1.35
pitch_deg = 4.0       # optical axis below the horizontal
yaw_deg = 0.0         # optional: optical axis to the left of the vehicle's x axis
roll_deg = 0.0        # optional: about the optical axis, + the camera's right side down
```
The rectified frame is the detector rig's image (its size, field of view, pitch and mount): below the rig's horizon
each pixel shows the ground point the rig sees there, taken from the calibrated camera (a flat-road homography
from the mount, pitch, yaw and roll), so the detector's nominal geometry decodes metres of the vehicle frame
whatever the camera's mount; above it each pixel shows the same direction (the plane at infinity), which meets
the ground map at the horizon. Pixels the camera does not see are black.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from testbed.errors import UserError
from vehicles.camera_rig import CameraRig
from vehicles.params import CameraParams

_REQUIRED_EXTRINSICS = ("mount_x", "mount_height", "pitch_deg")
_OPTIONAL_EXTRINSICS = ("mount_y", "yaw_deg", "roll_deg")
# OpenCV camera axes (x right, y down, z forward) in the vehicle frame (x ahead, y left, z up), level camera
_CV_AXES = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
DETECTOR_WINDOW = ((5.0, 30.0), 5.5)
"""Ground the detectors read (m): x from 5 to 30 ahead, |y| up to 5.5 (the ego lane and half the next ones)."""
MIN_COVERAGE = 0.9
"""Share of `DETECTOR_WINDOW` a camera must see for its calibration to suit the detector."""


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
    mount_y: float = 0.0
    yaw_deg: float = 0.0
    roll_deg: float = 0.0

    @classmethod
    def load(cls, path: Path) -> CameraCalibration:
        """Read the TOML file; a missing or malformed key is a one-line UserError naming it."""
        try:
            table = tomllib.loads(Path(path).read_text(encoding="utf-8"))
        except (OSError, tomllib.TOMLDecodeError, UnicodeDecodeError, RecursionError) as exc:
            raise UserError(f"camera calibration {path}: {exc}") from None
        try:
            intr, extr = table["intrinsics"], table["extrinsics"]
            values: dict[str, Any] = {key: int(intr[key]) for key in ("width", "height")}
            values.update({key: float(intr[key]) for key in ("fx", "fy", "cx", "cy")})
            values["distortion"] = tuple(float(k) for k in intr.get("distortion", ()))
            values.update({key: float(extr[key]) for key in _REQUIRED_EXTRINSICS})
            values.update({key: float(extr[key]) for key in _OPTIONAL_EXTRINSICS if key in extr})
        except (KeyError, TypeError, ValueError) as exc:
            raise UserError(f"camera calibration {path}: missing or bad entry {exc}") from None
        if len(values["distortion"]) not in (0, 4, 5, 8):
            raise UserError(f"camera calibration {path}: distortion takes 4, 5 or 8 OpenCV coefficients")
        if min(values["width"], values["height"]) <= 0 or min(values["fx"], values["fy"]) <= 0:
            raise UserError(f"camera calibration {path}: width, height, fx and fy must be positive")
        if values["mount_height"] <= 0:
            raise UserError(f"camera calibration {path}: mount_height must be above the ground (m)")
        return cls(**values)

    @property
    def matrix(self) -> np.ndarray:
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def vehicle_from_camera(self) -> np.ndarray:
        """Rotation (3, 3) of the camera's OpenCV axes into the vehicle frame: yaw, then pitch down, then roll."""
        yaw, pitch, roll = (math.radians(a) for a in (self.yaw_deg, self.pitch_deg, self.roll_deg))
        cz, sz, cp, sp, cr, sr = math.cos(yaw), math.sin(yaw), math.cos(pitch), math.sin(pitch), math.cos(roll), \
            math.sin(roll)
        rz = np.array([[cz, -sz, 0.0], [sz, cz, 0.0], [0.0, 0.0, 1.0]])
        ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])  # + pitches the axis down
        rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])  # + lifts the left side
        return rz @ ry @ rx @ _CV_AXES

    @property
    def mount(self) -> np.ndarray:
        return np.array([self.mount_x, self.mount_y, self.mount_height])

    def rig_params(self, detector: CameraParams) -> CameraParams:
        """The rig the rectified frames show: the detector's own (the rectification moves the road into it)."""
        return detector


class Rectifier:
    """Maps a calibrated camera's frames (H × W × 3) into `rig`'s image: OpenCV remap tables built once (see the
    module docstring); `coverage` is the share of `DETECTOR_WINDOW` the camera sees."""

    def __init__(self, calibration: CameraCalibration, rig: CameraRig) -> None:
        import cv2

        self._cv2 = cv2
        self.size = (calibration.width, calibration.height)
        v, u = np.mgrid[0 : rig.height, 0 : rig.width].astype(np.float64)
        uv = np.column_stack([u.ravel(), v.ravel()])
        source = source_pixels(calibration, rig, uv)
        self.maps = tuple(c.reshape(rig.height, rig.width).astype(np.float32) for c in source.T)
        self.coverage = window_coverage(calibration, rig)

    def __call__(self, image: np.ndarray) -> np.ndarray:
        if (image.shape[1], image.shape[0]) != self.size:
            raise ValueError(f"camera frame is {image.shape[1]}x{image.shape[0]}, its calibration "
                             f"{self.size[0]}x{self.size[1]}")
        return self._cv2.remap(image, *self.maps, self._cv2.INTER_LINEAR, borderMode=self._cv2.BORDER_CONSTANT)


def camera_points(calibration: CameraCalibration, rig: CameraRig, uv: np.ndarray) -> np.ndarray:
    """Rig pixels (N, 2) -> what the calibrated camera sees there, in its axes (N, 3): the ground point the rig's
    ray meets below the horizon, the ray's direction (a point at infinity) at and above it."""
    ground = rig.pixel_to_ground(uv)
    below = np.isfinite(ground).all(axis=1)
    camera_from_vehicle = calibration.vehicle_from_camera.T
    rays = np.column_stack([uv, np.ones(len(uv))]) @ np.linalg.inv(rig.K).T @ rig.T_vehicle_from_camera[:3, :3].T
    points = rays @ camera_from_vehicle.T
    road = np.column_stack([ground[below], np.zeros(int(below.sum()))]) - calibration.mount
    points[below] = road @ camera_from_vehicle.T
    return points


def source_pixels(calibration: CameraCalibration, rig: CameraRig, uv: np.ndarray) -> np.ndarray:
    """Rig pixels (N, 2) -> the calibrated camera's (distorted) pixels showing the same thing (N, 2); (-1, -1)
    where the camera does not see it (behind it, or outside its undistorted image)."""
    import cv2

    points = camera_points(calibration, rig, uv)
    ahead = points[:, 2] > 1e-9
    normal = np.full((len(uv), 2), np.inf)
    normal[ahead] = points[ahead, :2] / points[ahead, 2:]
    lo, hi = normal_bounds(calibration)
    seen = ahead & (normal >= lo).all(axis=1) & (normal <= hi).all(axis=1)
    out = np.full((len(uv), 2), -1.0)
    if seen.any():
        xyz = np.column_stack([normal[seen], np.ones(int(seen.sum()))])
        dist = np.array(calibration.distortion or (0.0,) * 4)
        projected, _ = cv2.projectPoints(xyz, np.zeros(3), np.zeros(3), calibration.matrix, dist)
        out[seen] = projected[:, 0, :]
    return out


def normal_bounds(calibration: CameraCalibration) -> tuple[np.ndarray, np.ndarray]:
    """Bounding box of the camera's image in undistorted normalised coordinates (where distortion is one-to-one)."""
    import cv2

    w, h = calibration.width, calibration.height
    u, v = np.linspace(-0.5, w - 0.5, 33), np.linspace(-0.5, h - 0.5, 33)
    edge = np.concatenate([np.column_stack([u, np.full_like(u, v[0])]), np.column_stack([u, np.full_like(u, v[-1])]),
                           np.column_stack([np.full_like(v, u[0]), v]), np.column_stack([np.full_like(v, u[-1]), v])])
    dist = np.array(calibration.distortion or (0.0,) * 4)
    normal = cv2.undistortPoints(edge[:, None, :], calibration.matrix, dist)[:, 0, :]
    return normal.min(axis=0), normal.max(axis=0)


def window_coverage(calibration: CameraCalibration, rig: CameraRig) -> float:
    """Share of the ground in `DETECTOR_WINDOW` the rig sees that the calibrated camera sees too."""
    (x0, x1), half = DETECTOR_WINDOW
    x, y = np.meshgrid(np.linspace(x0, x1, 26), np.linspace(-half, half, 23))
    uv = rig.ground_to_pixel(np.column_stack([x.ravel(), y.ravel()]))
    inside = np.isfinite(uv).all(axis=1) & (uv[:, 0] >= 0) & (uv[:, 0] <= rig.width - 1) & (uv[:, 1] >= 0) \
        & (uv[:, 1] <= rig.height - 1)
    if not inside.any():
        return 0.0
    src = source_pixels(calibration, rig, uv[inside])
    seen = (src[:, 0] >= 0) & (src[:, 0] <= calibration.width - 1) & (src[:, 1] >= 0) \
        & (src[:, 1] <= calibration.height - 1)
    return float(seen.mean())


def view_check(calibration: CameraCalibration, rig: CameraRig) -> str | None:
    """Why this camera does not suit the detector (it sees under `MIN_COVERAGE` of its ground), else None."""
    coverage = window_coverage(calibration, rig)
    if coverage >= MIN_COVERAGE:
        return None
    (x0, x1), half = DETECTOR_WINDOW
    return (f"the camera sees {coverage:.0%} of the road the detector reads (x {x0:g}-{x1:g} m ahead, |y| <= "
            f"{half:g} m); check pitch_deg, mount_height and the field of view (docs/camera.md)")
