"""The front camera: TinyRenderer images of the streamed road, and the image effects of each condition.

A condition is a lighting set-up passed in full on every render (PyBullet's lighting arguments are
sticky) and baked into the ground canvas, a sky, track painters (worn markings, shadow bands) and a
sensor model applied to the image in this order: exposure and headlight cone (night), sky fill,
contrast, blur, noise.

The camera renders any `RenderScene` (a PyBullet client and the ground canvas): `testbed.world.TileStreamer`
is one; the camera does not import the world.
"""

from __future__ import annotations

from typing import Protocol

import cv2
import numpy as np
import pybullet as pb

from testbed.conditions import Condition
from testbed.ground import OPEN_GROUND_RGBA, GroundCanvas, without_ipp
from testbed.lane_detection import CameraFrame
from testbed.tiny_boxes import TinyBoxes
from tracks.pose import Pose
from vehicles.camera_rig import CameraRig

NEAR_M, FAR_M = 0.3, 250.0
EMPTY_DEPTH = 0.9999
"""TinyRenderer depth at or beyond which nothing was drawn."""


class ImageEffects:
    """Sky, exposure, headlights, contrast, blur and noise of a condition for one camera rig."""

    def __init__(self, rig: CameraRig, condition: Condition) -> None:
        self.condition = condition
        h, w = rig.height, rig.width
        rows = np.linspace(0.0, 1.0, h)[:, None, None]
        top, hor = np.array(condition.sky_top, float), np.array(condition.sky_horizon, float)
        self.sky = (top * (1 - rows) + hor * rows) * np.ones((1, w, 1))
        self.below_horizon = self._below_horizon(rig)
        self.first_ground_row = int(np.argmax(self.below_horizon.any(axis=1)))
        self.ground_gain: np.ndarray | None = None
        """Per-pixel gain (exposure plus headlight cone) where it varies; None when it is the exposure alone."""
        if condition.headlights:
            self.ground_gain = (condition.exposure + self._headlight_gain(rig)).astype(np.float32)
        self.sky = self.sky.astype(np.float32)
        self._noise_bank: np.ndarray | None = None

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

    def apply(self, rgb: np.ndarray, sky: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """`rgb`: the lit scene (uint8); `sky`: pixels where nothing was drawn above the horizon."""
        c = self.condition
        img = rgb.astype(np.float32)
        if self.ground_gain is not None:
            img *= self.ground_gain
        elif c.exposure != 1.0:
            img *= np.float32(c.exposure)
        cv2.copyTo(self.sky, sky.view(np.uint8), img)
        if c.contrast != 1.0:
            mean = float(img.mean())
            img = cv2.addWeighted(img, c.contrast, img, 0.0, mean * (1.0 - c.contrast))
        if c.blur_sigma > 0:
            img = cv2.GaussianBlur(img, (0, 0), c.blur_sigma)
        if c.noise_std > 0:
            img = cv2.scaleAdd(self._noise(rng), c.noise_std, img)
        return np.clip(img, 0, 255, out=img).astype(np.uint8)

    def _noise(self, rng: np.random.Generator) -> np.ndarray:
        """Unit luma noise for one frame (the same value in the three channels): a random window of a bank
        drawn once (2× the frame each way) from `rng`, so each frame costs one offset draw instead of a fresh
        normal per pixel."""
        h, w = self.sky.shape[:2]
        if self._noise_bank is None:
            luma = rng.standard_normal((2 * h, 2 * w), dtype=np.float32)
            self._noise_bank = cv2.merge([luma, luma, luma])
        oy, ox = (int(v) for v in rng.integers(0, (h, w)))
        return self._noise_bank[oy : oy + h, ox : ox + w]


class RenderScene(Protocol):
    """What the camera renders: the roadside and traffic boxes for TinyRenderer's compiled clone, or (None) a PyBullet
    client holding them as bodies (and the road's tile meshes when there is no canvas), and the ground canvas the
    road surface is drawn from (None: no canvas)."""

    boxes: TinyBoxes | None
    client: int | None
    canvas: GroundCanvas | None


class FrontCamera:
    """Renders the rig's view: the road surface from the streamer's ground canvas (or TinyRenderer's
    ground meshes), roadside bodies from TinyRenderer, the sky, then the condition's effects."""

    def __init__(self, streamer: RenderScene, rig: CameraRig, condition: Condition, rng: np.random.Generator) -> None:
        self.streamer = streamer
        self.client = streamer.client
        self.rig = rig
        self.condition = condition
        self.rng = rng
        self.effects = ImageEffects(rig, condition)
        self.projection = rig.projection_matrix(NEAR_M, FAR_M)
        self._empty_scene: tuple[np.ndarray, np.ndarray] | None = None

    def scene(self, pose: Pose) -> tuple[np.ndarray, np.ndarray]:
        """TinyRenderer's picture of the scene's boxes (RGBA, and where nothing was drawn): by its compiled clone
        where the scene has the boxes, else by TinyRenderer from the render client. A scene without a body draws
        the same empty picture from every pose: that one is rendered once and reused."""
        c = self.condition
        boxes = self.streamer.boxes
        bodiless = boxes.body_count == 0 if boxes is not None else pb.getNumBodies(physicsClientId=self.client) == 0
        if bodiless and self._empty_scene is not None:
            rgba, empty = self._empty_scene
            return rgba.copy(), empty
        if boxes is not None:
            rgba, depth = boxes.render(self.rig.view_matrix(pose), self.projection, c.light_dir, c.light_rgb,
                                       c.ambient, c.diffuse, self.rig.width, self.rig.height)
            empty = depth >= EMPTY_DEPTH
        else:
            _, _, rgba, depth, _ = pb.getCameraImage(
                self.rig.width, self.rig.height, self.rig.view_matrix(pose), self.projection,
                lightDirection=list(c.light_dir), lightColor=list(c.light_rgb), lightDistance=100.0, shadow=0,
                lightAmbientCoeff=c.ambient, lightDiffuseCoeff=c.diffuse, lightSpecularCoeff=0.0,
                renderer=pb.ER_TINY_RENDERER, flags=pb.ER_NO_SEGMENTATION_MASK, physicsClientId=self.client,
            )
            shape = (self.rig.height, self.rig.width)
            rgba = np.reshape(np.asarray(rgba, dtype=np.uint8), (*shape, 4))
            empty = np.reshape(np.asarray(depth), shape) >= EMPTY_DEPTH
        if bodiless:
            empty.flags.writeable = False
            self._empty_scene = (rgba.copy(), empty)
        return rgba, empty

    @without_ipp
    def render(self, pose: Pose) -> np.ndarray:
        rgba, empty = self.scene(pose)
        below = self.effects.below_horizon
        canvas = self.streamer.canvas
        ground = (below & empty).view(np.uint8)
        if canvas is not None:
            top = self.effects.first_ground_row
            cv2.copyTo(canvas.view(self.rig, pose, top), ground[top:], rgba[top:])
        else:
            rgba[ground.view(bool)] = OPEN_GROUND_RGBA
        return self.effects.apply(cv2.cvtColor(rgba, cv2.COLOR_RGBA2RGB), empty & ~below, self.rng)

    def capture(self, t: float, pose: Pose) -> CameraFrame:
        return CameraFrame(t=t, image=self.render(pose), true_pose=pose)
