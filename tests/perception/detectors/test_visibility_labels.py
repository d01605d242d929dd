"""Existence labels from what the frame shows: paint against the surfaces on both sides of each lane line, row by
row, on synthetic frames of known contrast and on rendered ones."""

import itertools

import numpy as np
import pytest

from testbed.camera import FrontCamera
from testbed.conditions import get_condition
from testbed.perception.detectors.labels import (
    VISIBLE_CONTRAST,
    VISIBLE_FRACTION,
    FrameVisibility,
    PaintLayout,
    ego_lines,
)
from testbed.world import TileStreamer
from tests.perception.conftest import pose_on
from tracks.paint import AsphaltPainter, MarkingPainter, ShadowPainter, WearPainter, marking_coverage
from tracks.pose import Pose
from tracks.presets import load_track
from vehicles.camera_rig import CameraRig
from vehicles.params import get_vehicle

RIG = CameraRig(get_vehicle("sedan").camera)
ASPHALT, WHITE, KERB = (90.0, 90.0, 92.0), (236.0, 236.0, 230.0), (185.0, 183.0, 176.0)
YELLOW = (232.0, 182.0, 42.0)
S_CAR = 50.0  # both ego lines of lane 0 are painted from here to s = 100 on the fixture track


def _synthetic_frame(track, paint: dict[int, tuple[float, float, float]], kerb_gap: float | None = None,
                     yaw: float = 0.0) -> tuple[np.ndarray, Pose]:
    """The fixture's straight road seen from lane 0's centre at S_CAR: flat asphalt, boundary i's laid paint in
    colour `paint[i]`, and a kerb from `kerb_gap` m right of the right edge line outward. No lighting, no noise."""
    pose = pose_on(track, 0, S_CAR, 0.0, yaw)
    v, u = np.mgrid[0 : RIG.height, 0 : RIG.width]
    xy = RIG.pixel_to_ground(np.column_stack([u.ravel(), v.ravel()]).astype(float))
    c, s = np.cos(yaw), np.sin(yaw)
    road_s = S_CAR + c * xy[:, 0] - s * xy[:, 1]
    road_t = s * xy[:, 0] + c * xy[:, 1]
    ground = np.isfinite(xy).all(axis=1)
    img = np.zeros((RIG.height * RIG.width, 3))
    img[:] = (120.0, 160.0, 220.0)  # sky
    img[ground] = ASPHALT
    if kerb_gap is not None:
        img[ground & (road_t < track.boundaries[0].t - kerb_gap)] = KERB
    layout = PaintLayout(track)
    for i, colour in paint.items():
        b = track.boundaries[i]
        near = ground & (np.abs(road_t - b.t) < 0.3)
        cover = np.zeros(len(img))
        cover[near] = layout.coverage(road_s[near], road_t[near])
        img[near & (cover > 0.5) & (np.abs(road_t - b.t) < 0.2)] = colour
    return np.clip(img, 0, 255).astype(np.uint8).reshape(RIG.height, RIG.width, 3), pose


def _labels(track, image, pose):
    return ego_lines(track, pose, FrameVisibility(image, RIG, PaintLayout(track)))


def test_fresh_lines_are_present(track):
    image, pose = _synthetic_frame(track, {0: WHITE, 1: WHITE})
    lines = _labels(track, image, pose)
    assert lines.left.exists and lines.right.exists


def test_paint_worn_to_the_asphalt_is_missing(track):
    worn = tuple(a * (1.0 + 0.5 * VISIBLE_CONTRAST) for a in ASPHALT)
    image, pose = _synthetic_frame(track, {0: worn, 1: WHITE})
    lines = _labels(track, image, pose)
    assert not lines.right.exists
    assert lines.left.exists
    assert ego_lines(track, pose).right.exists  # painted on the map all the same


def test_worn_edge_line_merged_into_a_bright_kerb_is_missing(track):
    """Seen against the asphalt on its inner side, but of the kerb's shade on the outer side."""
    worn = tuple(0.5 * (a + k) + 0.5 * (k - a) * 0.8 for a, k in zip(ASPHALT, KERB, strict=True))
    image, pose = _synthetic_frame(track, {0: worn, 1: WHITE}, kerb_gap=0.10)
    lines = _labels(track, image, pose)
    assert not lines.right.exists
    assert lines.left.exists
    alone, _ = _synthetic_frame(track, {0: worn, 1: WHITE})  # the same paint with asphalt on both sides
    assert _labels(track, alone, pose).right.exists


def test_fresh_edge_line_beside_a_kerb_is_present(track):
    for colour in (WHITE, YELLOW):  # white is brighter than the kerb; yellow differs from it in hue
        image, pose = _synthetic_frame(track, {0: colour, 1: WHITE}, kerb_gap=0.10)
        assert _labels(track, image, pose).right.exists


def _fragmented(track, every: int) -> tuple[np.ndarray, Pose]:
    """The fixture frame with a fresh white right edge line worn back to the asphalt in all but every `every`-th
    image row of the view window: worn paint that survives in fragments."""
    image, pose = _synthetic_frame(track, {0: WHITE, 1: WHITE})
    rows = FrameVisibility(image, RIG, PaintLayout(track)).rows
    right_half = image[:, RIG.width // 2 :]
    for k, row in enumerate(rows):
        if k % every:
            right_half[row][(right_half[row] == WHITE).all(axis=-1)] = ASPHALT
    return image, pose


def test_a_worn_line_seen_in_fragments_is_present_and_one_seen_in_scattered_rows_is_not(track):
    """Fragments of fresh contrast along a fifth of the window make a line a driver sees; a row in twenty does not."""
    fragments, pose = _fragmented(track, 5)
    vis = FrameVisibility(fragments, RIG, PaintLayout(track))
    right = track.boundaries[0]
    s = np.arange(S_CAR - 5.0, S_CAR + 45.0, 1.0)
    seen = vis.visible_fraction(right.t, s, s - S_CAR, np.full_like(s, right.t - pose.y))
    assert VISIBLE_FRACTION <= seen < 0.25
    assert _labels(track, fragments, pose).right.exists
    scattered, _ = _fragmented(track, 20)
    assert not _labels(track, scattered, pose).right.exists
    assert _labels(track, scattered, pose).left.exists


def test_dash_gaps_are_not_judged_and_a_line_out_of_frame_is_not_seen(track):
    image, _ = _synthetic_frame(track, {0: WHITE, 1: WHITE})
    vis = FrameVisibility(image, RIG, PaintLayout(track))
    dashed = track.boundaries[1]
    s = np.arange(S_CAR - 5.0, S_CAR + 45.0, 1.0)
    x = s - S_CAR
    assert vis.visible_fraction(dashed.t, s, x, np.full_like(x, dashed.t)) == 1.0
    gone, _ = _synthetic_frame(track, {0: WHITE})  # the dashes are not drawn: every laid row shows asphalt
    assert FrameVisibility(gone, RIG, PaintLayout(track)).visible_fraction(
        dashed.t, s, x, np.full_like(x, dashed.t)) == 0.0
    far_left = 12.0  # m: outside the field of view over the whole window
    assert vis.visible_fraction(far_left, s, x, np.full_like(x, far_left)) is None


def test_a_frame_of_another_size_is_refused(track):
    with pytest.raises(ValueError, match="rig"):
        FrameVisibility(np.zeros((10, 10, 3), np.uint8), RIG, PaintLayout(track))


# ---- rendered frames --------------------------------------------------------------------------------------------

class _Fade:
    """Blends the paint toward the bare asphalt's median colour by `amount` (1: repaved)."""

    def __init__(self, amount: float) -> None:
        self.amount = amount

    def paint(self, img, frame, rng) -> None:
        cover = marking_coverage(frame)
        lo, hi = frame.track.paved_range
        t = frame.t_of_cols()
        paved = (t > lo) & (t < hi)
        base = np.median(img[:, paved][cover[:, paved] == 0], axis=0)
        a = self.amount * cover[..., None]
        img[:] = np.clip(img * (1.0 - a) + base * a + 0.5, 0, 255).astype(np.uint8)


def _render(track, pose: Pose, condition: str, *painters) -> np.ndarray:
    """The frame the camera renders at `pose` in `condition`, the track painted with `painters` too."""
    cond = get_condition(condition)
    track.painters = [AsphaltPainter(), MarkingPainter(), *painters, *cond.track_painters(track.seed)]
    streamer = TileStreamer(track, cond.lighting, ahead_m=70.0, behind_m=5.0)
    try:
        streamer.update(pose)
        return FrontCamera(streamer, RIG, cond, np.random.default_rng(5)).render(pose)
    finally:
        streamer.close()


def _rendered_fractions(track, pose: Pose, condition: str, *painters) -> tuple[float | None, float | None]:
    """(left, right) visible fractions of the ego lines in the frame the camera renders at `pose`."""
    vis = FrameVisibility(_render(track, pose, condition, *painters), RIG, PaintLayout(track))
    lines = ego_lines(track, pose, vis)
    out = []
    for boundary in (track.boundaries[lines.lane + 1], track.boundaries[lines.lane]):
        s = np.arange(pose.x - 5.0, pose.x + 45.0, 1.0)  # straight road along +x from the origin
        out.append(vis.visible_fraction(boundary.t, s, s - pose.x, np.full_like(s, boundary.t - pose.y)))
    return out[0], out[1]


def test_rendered_repaved_paint_is_missing_and_half_faded_paint_is_not(track):
    pose = pose_on(track, 0, S_CAR)
    assert min(_rendered_fractions(track, pose, "day")) > 0.95
    assert min(_rendered_fractions(track, pose, "day", _Fade(0.5))) > 0.95
    assert max(_rendered_fractions(track, pose, "day", _Fade(1.0))) < 0.1


def test_rendered_repaved_paint_stays_missing_in_the_noise_of_a_night_frame(track):
    """Sensor noise and asphalt grain alone pass the contrast test in some rows of a dark frame: fewer than
    `VISIBLE_FRACTION` of them."""
    pose = pose_on(track, 0, S_CAR)
    assert max(_rendered_fractions(track, pose, "night", _Fade(1.0))) < VISIBLE_FRACTION
    lines = _labels(track, _render(track, pose, "night", _Fade(1.0)), pose)
    assert not lines.left.exists and not lines.right.exists


def test_rendered_wear_leaves_less_visible_paint_the_more_it_wears(track):
    pose = pose_on(track, 0, 20.0)
    right = [_rendered_fractions(track, pose, "day", WearPainter(a))[1] for a in (0.0, 0.4, 0.8, 1.0)]
    assert right[0] > 0.95
    assert all(a > b for a, b in itertools.pairwise(right))
    assert right[-1] < 0.1


def test_rendered_shadow_over_a_line_leaves_it_visible(track):
    """Shadows darken paint and asphalt alike."""
    pose = pose_on(track, 0, 160.0)
    assert _rendered_fractions(track, pose, "day", ShadowPainter(darkness=0.6, per_100m=10.0))[1] > 0.95


def test_preset_frames_worn_against_day():
    """urban-straight's ego lane (a white edge line by a kerb, a dashed lane line), rendered in the day and the
    worn condition at the same stations: every fresh line is seen; worn paint shows in fewer rows and lines go
    missing."""
    track = load_track("urban-straight@9003")
    lane = track.lanes[track.ego_lane]
    poses = [Pose(*lane.position(s, 0.0), lane.heading_at(s)) for s in (60.0, 100.0, 140.0, 180.0, 220.0, 300.0)]
    assert all(all(_labels_rendered(track, pose, "day")) for pose in poses)
    assert sum(not v for pose in poses for v in _labels_rendered(track, pose, "worn")) >= 1
    day = np.mean([_rendered_fractions(track, pose, "day") for pose in poses])
    worn = np.mean([_rendered_fractions(track, pose, "worn") for pose in poses])
    assert day > 0.8 and worn < day - 0.2


def _labels_rendered(track, pose: Pose, condition: str) -> tuple[bool, bool]:
    lines = _labels(track, _render(track, pose, condition), pose)
    return lines.left.exists, lines.right.exists

