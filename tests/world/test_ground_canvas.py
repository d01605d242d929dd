"""The ground canvas against TinyRenderer drawing the same textured tile meshes, and its tile bookkeeping."""

import math

import cv2
import numpy as np
import pytest

from testbed.camera import FrontCamera
from testbed.conditions import get_condition
from testbed.ground import OPEN_GROUND_RGB, GroundCanvas, lit_levels
from testbed.world import TileStreamer
from tracks.pose import Pose
from tracks.presets import load_track
from tracks.texture import tile_frame, tile_texture
from vehicles.camera_rig import CameraRig
from vehicles.params import get_vehicle


def _frames(preset: str, condition: str, ground: str, stations: list[float]) -> list[np.ndarray]:
    track = load_track(preset)
    cond = get_condition(condition)
    track = track.with_painters(cond.track_painters(track.seed))
    streamer = TileStreamer(track, cond.lighting, ground=ground)
    rig = CameraRig(get_vehicle("sedan").camera)
    camera = FrontCamera(streamer, rig, cond, np.random.default_rng(3))
    lane = track.lanes[track.ego_lane]
    out = []
    try:
        for s in stations:
            pose = Pose(*lane.position(s, 0.4), lane.heading_at(s) - 0.03)
            streamer.update(pose)
            out.append(camera.render(pose))
    finally:
        streamer.close()
    return out


@pytest.mark.parametrize(("preset", "condition"), [("urban-curvy", "day"), ("highway", "night")])
def test_canvas_draws_the_road_as_tinyrenderer_draws_its_meshes(preset, condition):
    stations = [15.0, 140.0, 260.0]
    canvas = _frames(preset, condition, "canvas", stations)
    mesh = _frames(preset, condition, "mesh", stations)
    for a, b in zip(canvas, mesh, strict=True):
        a16, b16 = a.astype(np.int16), b.astype(np.int16)
        assert np.abs(a16 - b16).mean() < 4.0  # sampling of the asphalt grain differs (bilinear vs nearest)
        assert abs(a16.mean() - b16.mean()) < 1.0  # same lighting: no bias
        gray_a, gray_b = cv2.cvtColor(a, cv2.COLOR_RGB2GRAY), cv2.cvtColor(b, cv2.COLOR_RGB2GRAY)
        level = np.percentile(gray_b, 97)  # lane markings (and light roadside concrete), day or night
        bright_a, bright_b = gray_a > level, gray_b > level
        near_b = cv2.dilate(bright_b.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
        assert bright_a.sum() > 200
        assert (bright_a & near_b).sum() / bright_a.sum() > 0.9  # markings land on the same pixels (±1 px)


def test_canvas_holds_exactly_the_wanted_tiles_while_it_recentres():
    track = load_track("urban-curvy")
    canvas = GroundCanvas(track, get_condition("day").lighting, margin_m=15.0)
    for first in range(0, 12):
        canvas.set_tiles(set(range(first, first + 4)))
    assert canvas.rebuilds >= 2
    assert canvas.tiles == set(range(11, 15))

    def canvas_rgb(s: float, t: float) -> np.ndarray:
        x, y = track.reference.points(np.array([s]), np.array([t]))[0]
        col, row = (np.array([x, y]) - np.asarray(canvas.origin)) * canvas.ppm - 0.5
        assert 0 <= row < canvas.image.shape[0] and 0 <= col < canvas.image.shape[1]
        return canvas.image[round(row), round(col), :3].astype(int)

    L = track.tile_length
    assert (canvas_rgb(10.5 * L, 0.0) == OPEN_GROUND_RGB).all()  # dropped when the window moved on
    held = canvas_rgb(12.5 * L, 0.0)
    f = tile_frame(track, 12)
    row, col = (math.floor(v) for v in f.pixel(12.5 * L, 0.0))
    lit = np.clip(tile_texture(track, 12)[row, col] * canvas.gain, 0, 255)
    assert np.abs(held - lit).max() <= 25  # the texel there (neighbours differ by the grain)
    assert not (held == OPEN_GROUND_RGB).all()


def test_unknown_ground_mode_is_a_clear_error():
    with pytest.raises(ValueError, match="ground mode"):
        TileStreamer(load_track("slr"), get_condition("day").lighting, ground="voxels")


@pytest.mark.parametrize("preset", ["urban-curvy", "local", "highway"])
def test_canvas_keeps_the_lane_lines_where_the_map_has_them_on_the_sharpest_bend(preset):
    """Each lane line, composited on the canvas, lies on the map's line (within a few centimetres, the chords
    of the 2 m mesh segments included) where the road bends most."""
    track = load_track(preset)
    ref = track.reference
    s_bend = float(ref.s[int(np.argmax(np.abs(ref.curvature)))])
    canvas = GroundCanvas(track, get_condition("day").lighting)
    tile = int(s_bend // track.tile_length)
    canvas.set_tiles({tile})
    marked = [b for b in track.boundaries if b.kind_at(s_bend) in ("solid_white", "solid_yellow")]
    assert marked
    s = np.linspace(tile * track.tile_length + 0.5, (tile + 1) * track.tile_length - 0.5, 40)
    for boundary in marked:
        across = np.linspace(-0.25, 0.25, 51)  # m, sampled across the line (short of the kerbs)
        xy = ref.points(np.repeat(s, len(across)), np.tile(boundary.t + across, len(s)))
        col, row = ((xy - np.asarray(canvas.origin)) * canvas.ppm - 0.5).T
        rgb = canvas.image[np.round(row).astype(int), np.round(col).astype(int), :3].astype(float)
        bright = rgb[:, 0].reshape(len(s), len(across))  # red: white and yellow paint alike
        paint_centre = across[np.argmax(bright, axis=1)]
        assert np.abs(paint_centre).max() <= 0.06


@pytest.mark.parametrize("condition", ["day", "dusk", "night", "rain"])
def test_lit_levels_light_a_tile_as_the_diagonal_transform(condition):
    """Looking each byte up in `lit_levels` gives `cv2.transform`'s bytes, at every width (its vector body and
    scalar tail alike)."""
    gain = get_condition(condition).lighting.ground_gain()
    light = np.column_stack([np.diag(gain), [-0.5] * 3])
    rng = np.random.default_rng(8)
    for width in (*range(1, 40), 241, 397, 586):
        img = rng.integers(0, 256, (23, width, 3), dtype=np.uint8)
        assert np.array_equal(cv2.LUT(img, lit_levels(gain)), cv2.transform(img, light)), width


def test_canvas_and_camera_draw_with_opencv_ipp_off_and_restore_it(monkeypatch):
    """Every OpenCV call the canvas and the camera make to draw runs with IPP off (its warps round differently
    and are taken or not by CPU), on whichever thread draws; the thread's own setting is back after."""
    seen: list[tuple[str, bool]] = []

    def spy(name: str, real):
        def call(*args, **kwargs):
            seen.append((name, cv2.ipp.useIPP()))
            return real(*args, **kwargs)
        return call

    for name in ("warpPerspective", "fillConvexPoly", "LUT", "transform", "cvtColor", "copyTo", "scaleAdd"):
        monkeypatch.setattr(cv2, name, spy(name, getattr(cv2, name)))
    before = cv2.ipp.useIPP()
    frames = _frames("urban-curvy", "night", "canvas", [8.0, 140.0])
    assert len(frames) == 2 and cv2.ipp.useIPP() == before
    assert {name for name, _ in seen} >= {"warpPerspective", "fillConvexPoly", "LUT", "cvtColor", "scaleAdd"}
    assert not any(used for _, used in seen)
