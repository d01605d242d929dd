"""Front camera rig: a pinhole camera on the vehicle, its intrinsics, extrinsics and flat-ground homography.

Camera frame is OpenCV's (x right, y down, z forward); pixel (u, v) has u to the right and v down, with
pixel centres at integer coordinates and row 0 at the top of the image, matching what PyBullet renders
with `view_matrix` and `projection_matrix` (square pixels, principal point at the image centre).
The ground is the plane z = 0 of the vehicle frame; the camera sits `mount_x` ahead of the reference
point, `mount_height` above the ground, pitched down by `pitch`.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from tracks.pose import Pose
from vehicles.params import CameraParams

# OpenCV camera axes expressed in the vehicle frame at zero pitch (columns: x right, y down, z forward).
_CV_AXES = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
_CV_TO_GL = np.diag([1.0, -1.0, -1.0, 1.0])


class CameraRig:
    """A pinhole camera mounted on the vehicle; projects vehicle-frame ground points to pixels and back."""

    def __init__(self, params: CameraParams) -> None:
        self.params = params
        self.width = params.width
        self.height = params.height
        self.fov = math.radians(params.fov_deg)
        self.pitch = math.radians(params.pitch_deg)
        self.mount_x = params.mount_x
        self.mount_height = params.mount_height

        f = (self.height / 2.0) / math.tan(self.fov / 2.0)
        self.K = np.array(
            [[f, 0.0, (self.width - 1) / 2.0], [0.0, f, (self.height - 1) / 2.0], [0.0, 0.0, 1.0]]
        )
        c, s = math.cos(self.pitch), math.sin(self.pitch)
        pitch_down = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
        self.T_vehicle_from_camera = np.eye(4)
        self.T_vehicle_from_camera[:3, :3] = pitch_down @ _CV_AXES
        self.T_vehicle_from_camera[:3, 3] = (self.mount_x, 0.0, self.mount_height)

        rot_cv = self.T_vehicle_from_camera[:3, :3].T
        trans_cv = -rot_cv @ self.T_vehicle_from_camera[:3, 3]
        self.H = self.K @ np.column_stack((rot_cv[:, 0], rot_cv[:, 1], trans_cv))
        self._H_inv = np.linalg.inv(self.H)

    def with_jitter(self, pitch_delta: float, height_delta: float) -> CameraRig:
        """The same rig pitched further down by `pitch_delta` (rad) and raised by `height_delta` (m)."""
        return CameraRig(
            dataclasses.replace(
                self.params,
                pitch_deg=self.params.pitch_deg + math.degrees(pitch_delta),
                mount_height=self.params.mount_height + height_delta,
            )
        )

    def ground_to_pixel(self, xy: np.ndarray) -> np.ndarray:
        """Vehicle-frame ground points (N, 2) -> pixels (N, 2); NaN where not in front of the camera."""
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        proj = np.column_stack((xy, np.ones(len(xy)))) @ self.H.T
        # proj[:, 2] is the depth along the optical axis (the last row of K is (0, 0, 1)).
        ahead = proj[:, 2] > 1e-9
        uv = np.full_like(xy, np.nan)
        uv[ahead] = proj[ahead, :2] / proj[ahead, 2:3]
        return uv

    def pixel_to_ground(self, uv: np.ndarray) -> np.ndarray:
        """Pixels (N, 2) -> vehicle-frame ground points (N, 2); NaN for pixels at or above the horizon."""
        uv = np.asarray(uv, dtype=float).reshape(-1, 2)
        g = np.column_stack((uv, np.ones(len(uv)))) @ self._H_inv.T
        # g = (x, y, 1) / depth: rays at or above the horizon give depth <= 0 (or infinite).
        ahead = g[:, 2] > 1e-12
        xy = np.full_like(uv, np.nan)
        xy[ahead] = g[ahead, :2] / g[ahead, 2:3]
        return xy

    def view_matrix(self, pose: Pose) -> list[float]:
        """OpenGL view matrix (world -> camera) for a car at `pose`, column-major for `p.getCameraImage`."""
        c, s = math.cos(pose.yaw), math.sin(pose.yaw)
        world_from_vehicle = np.array(
            [[c, -s, 0.0, pose.x], [s, c, 0.0, pose.y], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]
        )
        world_from_camera = world_from_vehicle @ self.T_vehicle_from_camera
        view = _CV_TO_GL @ np.linalg.inv(world_from_camera)
        return [float(v) for v in view.T.ravel()]

    def projection_matrix(self, near: float, far: float, tiny_renderer: bool = True) -> list[float]:
        """OpenGL perspective projection for this field of view and aspect ratio, column-major.

        PyBullet's TinyRenderer (the one available in DIRECT mode) samples each pixel at its corner, half
        a pixel left of and below its centre; with `tiny_renderer` the frustum is shifted by that half
        pixel so the rendered image obeys `K` exactly. Without it this is OpenGL's centred frustum
        (`p.computeProjectionMatrixFOV`), right for renderers that sample at pixel centres.
        """
        f = 1.0 / math.tan(self.fov / 2.0)
        aspect = self.width / self.height
        sx, sy = (1.0 / self.width, 1.0 / self.height) if tiny_renderer else (0.0, 0.0)
        proj = np.array(
            [
                [f / aspect, 0.0, sx, 0.0],
                [0.0, f, sy, 0.0],
                [0.0, 0.0, (far + near) / (near - far), 2.0 * far * near / (near - far)],
                [0.0, 0.0, -1.0, 0.0],
            ]
        )
        return [float(v) for v in proj.T.ravel()]
