"""The front camera: TinyRenderer images of the streamed road, and the image effects of each condition.

A condition is a lighting set-up passed in full on every render (PyBullet's lighting arguments are
sticky), a sky, track painters (worn markings, shadow bands) and a sensor model applied to the image
in this order: sky fill, exposure, headlight cone (night), contrast, blur, noise.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
import pybullet as pb

from testbed.perception.detection import CameraFrame
from tracks.paint import ShadowPainter, WearPainter
from tracks.pose import Pose
from vehicles.camera_rig import CameraRig

NEAR_M, FAR_M = 0.3, 250.0
GROUND_RGB = (84.0, 107.0, 66.0)


@dataclass(frozen=True)
class Condition:
    """Lighting, sky and sensor model of one driving condition."""

    name: str
    ambient: float
    diffuse: float
    light_dir: tuple[float, float, float]
    light_rgb: tuple[float, float, float]
    sky_top: tuple[int, int, int]
    sky_horizon: tuple[int, int, int]
    exposure: float = 1.0
    contrast: float = 1.0
    blur_sigma: float = 0.0
    noise_std: float = 2.0
    headlights: bool = False
    wear: float = 0.0
    shadows: bool = False

    def track_painters(self, seed: int) -> list:
        """Painters the condition adds to the road texture (worn markings, shadow bands)."""
        painters: list = []
        if self.wear > 0:
            painters.append(WearPainter(self.wear))
        if self.shadows:
            painters.append(ShadowPainter())
        return painters


CONDITIONS: dict[str, Condition] = {
    c.name: c
    for c in (
        Condition("day", 0.65, 0.45, (0.4, 0.3, 1.0), (1.0, 1.0, 0.97), (110, 160, 220), (200, 220, 240)),
        Condition("dusk", 0.45, 0.35, (-1.0, 0.2, 0.25), (1.0, 0.75, 0.55), (60, 60, 110), (230, 140, 90),
                  exposure=0.75, contrast=0.85, noise_std=4.0),
        Condition("night", 0.30, 0.15, (0.0, 0.0, 1.0), (0.6, 0.65, 0.8), (5, 8, 18), (15, 18, 30),
                  exposure=0.22, contrast=1.0, noise_std=5.0, headlights=True),
        Condition("rain", 0.55, 0.25, (0.2, 0.2, 1.0), (0.85, 0.87, 0.9), (120, 125, 130), (150, 155, 160),
                  exposure=0.85, contrast=0.6, blur_sigma=1.1, noise_std=6.0),
        Condition("worn", 0.65, 0.45, (0.4, 0.3, 1.0), (1.0, 1.0, 0.97), (110, 160, 220), (200, 220, 240),
                  wear=0.65),
        Condition("shadows", 0.65, 0.45, (0.4, 0.3, 1.0), (1.0, 1.0, 0.97), (110, 160, 220), (200, 220, 240),
                  shadows=True),
    )
}


def get_condition(name: str) -> Condition:
    try:
        return CONDITIONS[name]
    except KeyError:
        raise ValueError(f"unknown condition {name!r}; choose one of {', '.join(CONDITIONS)}") from None


class ImageEffects:
    """Sky, exposure, headlights, contrast, blur and noise of a condition for one camera rig."""

    def __init__(self, rig: CameraRig, condition: Condition) -> None:
        self.condition = condition
        h, w = rig.height, rig.width
        rows = np.linspace(0.0, 1.0, h)[:, None, None]
        top, hor = np.array(condition.sky_top, float), np.array(condition.sky_horizon, float)
        self.sky = (top * (1 - rows) + hor * rows) * np.ones((1, w, 1))
        self.below_horizon = self._below_horizon(rig)
        gain = np.full((h, w, 1), condition.exposure, np.float32)
        if condition.headlights:
            gain += self._headlight_gain(rig).astype(np.float32)
        self.ground_gain = gain
        self.sky = self.sky.astype(np.float32)

    @staticmethod
    def _below_horizon(rig: CameraRig) -> np.ndarray:
        """Pixels whose ray meets the flat ground (where nothing was drawn there, it is open ground)."""
        v, u = np.mgrid[0 : rig.height, 0 : rig.width]
        uv = np.stack([u.ravel() + 0.5, v.ravel() + 0.5], axis=1).astype(float)
        return np.isfinite(rig.pixel_to_ground(uv)).all(axis=1).reshape(rig.height, rig.width)

    @staticmethod
    def _headlight_gain(rig: CameraRig) -> np.ndarray:
        """Illumination gain of a low-beam cone on flat ground, per pixel (1 beyond its reach is dark)."""
        v, u = np.mgrid[0 : rig.height, 0 : rig.width]
        uv = np.stack([u.ravel() + 0.5, v.ravel() + 0.5], axis=1).astype(float)
        gain = np.zeros(len(uv))
        xy = rig.pixel_to_ground(uv)
        ok = np.isfinite(xy).all(axis=1) & (xy[:, 0] > 0.5)
        x, y = xy[ok, 0], xy[ok, 1]
        gain[ok] = 3.8 * np.exp(-((x / 45.0) ** 2)) * np.exp(-((np.arctan2(y, x) / 0.30) ** 2))
        return gain.reshape(rig.height, rig.width, 1)

    def apply(self, rgb: np.ndarray, empty: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """`empty` marks pixels where nothing was rendered: open ground below the horizon, sky above."""
        c = self.condition
        img = rgb.astype(np.float32)
        img[empty & self.below_horizon] = GROUND_RGB
        sky_mask = empty & ~self.below_horizon
        img *= np.where(sky_mask[..., None], np.float32(1.0), self.ground_gain)
        img[sky_mask] = self.sky[sky_mask]
        if c.contrast != 1.0:
            mean = float(img.mean())
            img = cv2.addWeighted(img, c.contrast, img, 0.0, mean * (1.0 - c.contrast))
        if c.blur_sigma > 0:
            img = cv2.GaussianBlur(img, (0, 0), c.blur_sigma)
        if c.noise_std > 0:
            luma_noise = rng.standard_normal(img.shape[:2], dtype=np.float32) * np.float32(c.noise_std)
            img += luma_noise[..., None]
        return np.clip(img, 0, 255).astype(np.uint8)


class FrontCamera:
    """Renders the rig's view from the render client and applies the condition's effects."""

    def __init__(self, render_client: int, rig: CameraRig, condition: Condition, rng: np.random.Generator) -> None:
        self.client = render_client
        self.rig = rig
        self.condition = condition
        self.rng = rng
        self.effects = ImageEffects(rig, condition)
        self.projection = rig.projection_matrix(NEAR_M, FAR_M)

    def render(self, pose: Pose) -> np.ndarray:
        c = self.condition
        _, _, rgba, depth, _ = pb.getCameraImage(
            self.rig.width, self.rig.height, self.rig.view_matrix(pose), self.projection,
            lightDirection=list(c.light_dir), lightColor=list(c.light_rgb), lightDistance=100.0, shadow=0,
            lightAmbientCoeff=c.ambient, lightDiffuseCoeff=c.diffuse, lightSpecularCoeff=0.0,
            renderer=pb.ER_TINY_RENDERER, flags=pb.ER_NO_SEGMENTATION_MASK, physicsClientId=self.client,
        )
        rgb = np.reshape(np.asarray(rgba, dtype=np.uint8), (self.rig.height, self.rig.width, 4))[:, :, :3]
        sky = np.reshape(np.asarray(depth), (self.rig.height, self.rig.width)) >= 0.9999
        return self.effects.apply(rgb, sky, self.rng)

    def capture(self, t: float, pose: Pose) -> CameraFrame:
        return CameraFrame(t=t, image=self.render(pose), true_pose=pose)
