"""The road surface as the camera sees it: streamed tiles composited into a world-aligned bird's-eye
canvas, and the camera's view of the flat ground rendered as one homography of that canvas.

The world is flat (the road lies at z = 0) and the camera is a pinhole, so the image of the ground is a
projective map of the ground plane: drawing the canvas through `K·[r1 r2 t]` gives what a rasteriser
draws from the same textured mesh, at a fraction of the cost. Lighting is TinyRenderer's Lambert model
(ambient + diffuse·max(0, n·l)·light colour) for the surface normal +z, one gain per colour channel,
applied when a tile is composited. Pixels beyond the tiles are open ground (`OPEN_GROUND_RGB`). The canvas
holds four channels (RGB and an unused fourth): OpenCV warps four-channel pixels with the same per-channel
arithmetic as three-channel ones, and faster. Every OpenCV call that draws runs with Intel IPP off
(`without_ipp`): IPP's warps round differently from OpenCV's own code and pick their code by CPU.

Tile i covers the arc-length band [s_i, s_i+1); its texture is straight in (s, t) and the road's
curvature lives in the mesh. Each mesh segment (a quad between two cross sections `spacing` m apart) is
warped from the texture into the canvas with its own perspective transform, as the rasteriser maps
each pair of triangles; on curves the segment is cut into lateral strips first, so the warp keeps the
lane lines where the map has them.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import ParamSpec, TypeVar

import cv2
import numpy as np

from tracks.pose import Pose
from tracks.texture import tile_frame, tile_texture
from vehicles.camera_rig import CameraRig

OPEN_GROUND_RGB = (84, 107, 66)
OPEN_GROUND_RGBA = (*OPEN_GROUND_RGB, 255)
SEGMENT_SPACING_M = 2.0
MAX_WARP_ERROR_M = 0.005  # m: largest lateral misplacement of the road texture by a segment's warp
BUFFER_HEADROOM = 1.25
"""A canvas buffer holds this much more than the canvas it is made for, so that the buffer it leaves at the next
recentre still fits the one after (a canvas grows by a tenth or so once the road ahead bends): no fresh pages."""

P = ParamSpec("P")
R = TypeVar("R")


def without_ipp(draw: Callable[P, R]) -> Callable[P, R]:
    """`draw` run with OpenCV's Intel IPP paths off on the calling thread (OpenCV keeps the switch per thread), its
    previous setting restored after: the bytes are OpenCV's own code's, whatever code IPP would pick on the CPU
    (IPP's warps differ from OpenCV's by ±1 in about one pixel in a thousand)."""
    @functools.wraps(draw)
    def drawn(*args: P.args, **kwargs: P.kwargs) -> R:
        used = cv2.ipp.useIPP()
        cv2.ipp.setUseIPP(False)
        try:
            return draw(*args, **kwargs)
        finally:
            cv2.ipp.setUseIPP(used)
    return drawn


@dataclass(frozen=True)
class Lighting:
    """TinyRenderer's light for a horizontal surface: per-channel gain ambient + diffuse·max(0, n·l)·colour."""

    ambient: float
    diffuse: float
    direction: tuple[float, float, float]
    colour: tuple[float, float, float]

    def ground_gain(self) -> np.ndarray:
        d = np.asarray(self.direction, dtype=float)
        cos_inc = max(0.0, float(d[2] / np.linalg.norm(d)))
        return self.ambient + self.diffuse * cos_inc * np.asarray(self.colour, dtype=float)


@without_ipp
def lit_levels(gain: np.ndarray) -> np.ndarray:
    """The lit value of every byte in each channel, (1, 256, 3) uint8 for `cv2.LUT`: `cv2.transform` by the diagonal
    gain, whose -0.5 offset turns cv2's rounding into TinyRenderer's truncation of the lit colour. A channel's lit
    value depends on its own byte alone (the other channels' terms are exact zeros), so looking the bytes up gives
    the transform's bytes at a fraction of its cost."""
    levels = np.repeat(np.arange(256, dtype=np.uint8)[None, :, None], 3, axis=2)
    return cv2.transform(levels, np.column_stack([np.diag(gain), [-0.5] * 3]))


class GroundCanvas:
    """World-aligned canvas (RGBA uint8, alpha unused, `px_per_m` px per metre) holding the lit textures of a
    set of tiles.

    `set_tiles` composites newly wanted tiles and erases dropped ones; when a wanted tile falls outside
    the canvas, it is re-centred on them (with `margin_m` around them), carrying over what it already holds.
    """

    def __init__(self, track, lighting: Lighting, margin_m: float = 25.0) -> None:
        self.track = track
        self.ppm = float(track.px_per_m)
        self.gain = lighting.ground_gain()
        self.light = lit_levels(self.gain)
        """Each channel's 256 byte values as lit (`lit_levels`): a tile is lit by looking its bytes up."""
        self.margin = margin_m
        self.tiles: set[int] = set()
        self.rebuilds = 0
        self.origin = (0.0, 0.0)
        self.image = np.empty((0, 0, 4), np.uint8)
        self._spare = np.empty(0, np.uint8)
        """The buffer of the canvas before the last recentre, reused by the next one (no fresh pages to fault)."""
        self._segments: dict[int, list[tuple[np.ndarray, np.ndarray, slice]]] = {}
        self._textures: dict[int, np.ndarray] = {}

    # ---- canvas coordinates: pixel (col, row) centre of (j, i) is world (x0 + (j+0.5)/ppm, y0 + (i+0.5)/ppm)
    def _to_canvas(self, xy: np.ndarray) -> np.ndarray:
        return (xy - np.asarray(self.origin)) * self.ppm - 0.5

    def _contains(self, xy: np.ndarray) -> bool:
        c = self._to_canvas(xy)
        h, w = self.image.shape[:2]
        return bool(np.all(c >= 0) and np.all(c[:, 0] <= w - 1) and np.all(c[:, 1] <= h - 1))

    @without_ipp
    def set_tiles(self, wanted: set[int]) -> None:
        """Make the canvas hold exactly the `wanted` tiles."""
        if wanted == self.tiles and self.image.size:
            return  # the streamer asks every frame; the set changes once a tile length
        for i in sorted(self.tiles - wanted):
            self._erase(i)
        self.tiles &= wanted
        self._segments = {i: seg for i, seg in self._segments.items() if i in wanted}
        self._textures = {i: tex for i, tex in self._textures.items() if i in wanted}
        for i in wanted - self._segments.keys():
            self._segments[i] = self._tile_segments(i)
        if wanted:
            corners = np.concatenate([seg[1] for i in wanted for seg in self._segments[i]])
            if self.image.size == 0 or not self._contains(corners):
                self._recentre(corners)
        for i in sorted(wanted - self.tiles):
            self._paint(i)
        self.tiles = set(wanted)

    def _recentre(self, corners: np.ndarray) -> None:
        """New bounds around `corners`; what the old canvas holds (whole tiles only) is carried over."""
        lo = corners.min(axis=0) - self.margin
        hi = corners.max(axis=0) + self.margin
        old, old_origin = self.image, np.asarray(self.origin)
        if old.size:
            lo = old_origin + np.round((lo - old_origin) * self.ppm) / self.ppm  # on the old pixel grid
        w, h = (int(v) for v in np.ceil((hi - lo) * self.ppm))
        spare = self._spare if self._spare.size >= h * w * 4 else np.empty(int(h * w * 4 * BUFFER_HEADROOM), np.uint8)
        image = spare[: h * w * 4].reshape(h, w, 4)
        x0 = y0 = x1 = y1 = 0  # the region carried over
        if old.size:
            dx, dy = (int(v) for v in np.round((old_origin - lo) * self.ppm))
            cx0, cy0, cx1, cy1 = max(0, dx), max(0, dy), min(w, dx + old.shape[1]), min(h, dy + old.shape[0])
            if cx1 > cx0 and cy1 > cy0:
                x0, y0, x1, y1 = cx0, cy0, cx1, cy1
                image[y0:y1, x0:x1] = old[y0 - dy : y1 - dy, x0 - dx : x1 - dx]
        pixels = image.view(np.uint32)[..., 0]
        open_ground = np.array(OPEN_GROUND_RGBA, np.uint8).view(np.uint32)[0]
        for rows, cols in ((slice(0, y0), slice(None)), (slice(y1, h), slice(None)), (slice(y0, y1), slice(0, x0)),
                           (slice(y0, y1), slice(x1, w))):
            pixels[rows, cols] = open_ground  # open ground around what was carried over
        self._spare = old.base if old.base is not None else old.reshape(-1)
        self.image, self.origin = image, (float(lo[0]), float(lo[1]))
        self.rebuilds += 1

    def _tile_segments(self, i: int) -> list[tuple[np.ndarray, np.ndarray, slice]]:
        """Per mesh segment and lateral strip: texture corners (4, 2) in texture pixels, world corners (4, 2),
        texture rows. A perspective warp puts a strip of width w on an arc of curvature k up to k·w²/4 off its
        true place across the road (its cross-sections meet at the arc's centre), so strips are narrow enough
        to keep that under `MAX_WARP_ERROR_M`."""
        f = tile_frame(self.track, i)
        n = max(1, math.ceil((f.s1 - f.s0) / SEGMENT_SPACING_M))
        s = np.linspace(f.s0, f.s1, n + 1)
        out = []
        for k in range(n):
            curvature = max(abs(self.track.reference.curvature_at(float(v))) for v in np.linspace(s[k], s[k + 1], 5))
            strips = max(1, math.ceil((f.t_max - f.t_min) * math.sqrt(curvature / (4.0 * MAX_WARP_ERROR_M))))
            t = np.linspace(f.t_max, f.t_min, strips + 1)
            quad_s = np.array([s[k + 1], s[k + 1], s[k], s[k]])
            tex_v = (f.s1 - quad_s) * f.px_per_m_s - 0.5
            rows = slice(max(0, math.floor(tex_v.min()) - 1), min(f.height, math.ceil(tex_v.max()) + 2))
            for j in range(strips):
                quad_t = np.array([t[j], t[j + 1], t[j + 1], t[j]])
                tex = np.column_stack([(f.t_max - quad_t) * f.px_per_m_t - 0.5, tex_v])
                world = self.track.reference.points(quad_s, quad_t)
                out.append((tex, np.asarray(world, dtype=float), rows))
        return out

    def texture(self, i: int) -> np.ndarray:
        """Tile i's texture as lit on this canvas, RGBA (cached while the tile is held)."""
        if i not in self._textures:
            self._textures[i] = cv2.cvtColor(cv2.LUT(tile_texture(self.track, i), self.light), cv2.COLOR_RGB2RGBA)
        return self._textures[i]

    def _paint(self, i: int) -> None:
        tex = self.texture(i)
        for tex_quad, world_quad, rows in self._segments[i]:
            self._fill_quad(world_quad, tex[rows], tex_quad - np.array([0.0, rows.start]))

    def _erase(self, i: int) -> None:
        for _, world_quad, _ in self._segments[i]:
            self._fill_quad(world_quad, None, None)

    def _fill_quad(self, world_quad: np.ndarray, src: np.ndarray | None, src_quad: np.ndarray | None) -> None:
        """Draw one segment: warp `src` (None: open ground) onto the canvas quad, clipped to the canvas."""
        dst = self._to_canvas(world_quad)
        h, w = self.image.shape[:2]
        x0, y0 = (max(0, math.floor(v) - 1) for v in dst.min(axis=0))
        x1, y1 = (math.ceil(v) + 2 for v in dst.max(axis=0))
        x1, y1 = min(w, x1), min(h, y1)
        if x1 <= x0 or y1 <= y0:
            return
        local = dst - np.array([x0, y0])
        corners = np.round(local * 16).astype(np.int32)
        roi = self.image[y0:y1, x0:x1]
        if src is None:
            cv2.fillConvexPoly(roi, corners, OPEN_GROUND_RGBA, lineType=cv2.LINE_8, shift=4)
            return
        mask = np.zeros((y1 - y0, x1 - x0), np.uint8)
        cv2.fillConvexPoly(mask, corners, 1, lineType=cv2.LINE_8, shift=4)
        m = cv2.getPerspectiveTransform(src_quad.astype(np.float32), local.astype(np.float32))
        warped = cv2.warpPerspective(src, m, (x1 - x0, y1 - y0), flags=cv2.INTER_LINEAR,
                                     borderMode=cv2.BORDER_REPLICATE)
        cv2.copyTo(warped, mask, roi)

    @without_ipp
    def view(self, rig: CameraRig, pose: Pose, top_row: int = 0) -> np.ndarray:
        """The canvas as the rig sees it from `pose`: image rows `top_row`.. (RGBA uint8, alpha unused). Only
        pixels below the horizon mean anything; rows above the first such row need not be drawn."""
        c, s = math.cos(pose.yaw), math.sin(pose.yaw)
        vehicle_from_world = np.array([[c, s, -(c * pose.x + s * pose.y)], [-s, c, s * pose.x - c * pose.y],
                                       [0.0, 0.0, 1.0]])
        world_from_canvas = np.array([[1.0 / self.ppm, 0.0, self.origin[0] + 0.5 / self.ppm],
                                      [0.0, 1.0 / self.ppm, self.origin[1] + 0.5 / self.ppm], [0.0, 0.0, 1.0]])
        shift_rows = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, -top_row], [0.0, 0.0, 1.0]])
        m = shift_rows @ rig.H @ vehicle_from_world @ world_from_canvas
        return cv2.warpPerspective(self.image, m, (rig.width, rig.height - top_row), flags=cv2.INTER_LINEAR,
                                   borderMode=cv2.BORDER_CONSTANT, borderValue=OPEN_GROUND_RGBA)
