import itertools
import math
from functools import partial

import numpy as np
import pytest

from testbed.perception.labels import PaintVisibility, ego_lines
from tests.perception.conftest import ARC_R, LANE_W, pose_on
from tracks.map_api import OffMapError
from tracks.paint import AsphaltPainter, MarkingPainter, ShadowPainter, WearPainter, marking_coverage
from tracks.pose import Pose
from tracks.texture import tile_texture


@pytest.mark.parametrize(("lane", "offset", "yaw_deg"), [(0, 0.0, 0.0), (0, 0.4, 3.0), (1, -1.2, -5.0)])
def test_straight_road_gives_known_lines(track, lane, offset, yaw_deg):
    psi = math.radians(yaw_deg)
    truth = ego_lines(track, pose_on(track, lane, 30.0, offset, psi))
    assert truth.lane == lane
    assert truth.width == pytest.approx(LANE_W)
    assert truth.deviation == pytest.approx(offset, abs=1e-6)
    # a straight line at lateral offset d from the car, car yawed psi: y(x) = d / cos psi - x tan psi
    for coeffs, d in ((truth.left.coeffs, LANE_W / 2 - offset), (truth.right.coeffs, -LANE_W / 2 - offset)):
        np.testing.assert_allclose(coeffs, [d / math.cos(psi), -math.tan(psi), 0.0, 0.0], atol=2e-3)
    assert truth.left.exists and truth.right.exists
    assert truth.left.kind == ("dashed_white" if lane == 0 else "solid_yellow")


def test_arc_gives_curvature(track):
    truth = ego_lines(track, pose_on(track, 0, 215.0))
    c = truth.left.coeffs
    assert c[0] == pytest.approx(LANE_W / 2, abs=0.01)
    # y ≈ x² / (2 R') with R' the left line's radius (R - its offset)
    assert 2 * c[2] == pytest.approx(1.0 / (ARC_R - LANE_W / 2), rel=0.1)


def test_missing_lines(track):
    assert not ego_lines(track, pose_on(track, 0, 110.0)).right.exists  # unmarked stretch
    assert ego_lines(track, pose_on(track, 0, 110.0)).left.exists
    assert ego_lines(track, pose_on(track, 1, 110.0)).right.exists  # the lane line there is painted
    at_crossing = ego_lines(track, pose_on(track, 0, 398.0))
    assert not at_crossing.left.exists and not at_crossing.right.exists


def test_off_map_raises(track):
    with pytest.raises(OffMapError):
        ego_lines(track, Pose(30.0, 50.0, 0.0))
    with pytest.raises(OffMapError):
        ego_lines(track, Pose(math.nan, 0.0, 0.0))


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


def _visibility(track, *painters):
    track.painters = [AsphaltPainter(), MarkingPainter(), *painters]
    return PaintVisibility(track, partial(tile_texture, track))


def test_repaved_paint_is_a_missing_line_and_half_faded_paint_is_not(track):
    """At s = 50 both ego lines of lane 0 are painted. Paint blended into the asphalt colour is a missing
    line once the textures are consulted (only the asphalt grain is left to measure); faded to half its
    contrast it is still seen; the geometric label alone says painted either way."""
    pose = pose_on(track, 0, 50.0)
    fresh = _visibility(track)
    assert fresh.visible_fraction(track.boundaries[0].t, 55.0, 75.0) > 0.95
    half = _visibility(track, _Fade(0.5))
    assert half.visible_fraction(track.boundaries[0].t, 55.0, 75.0) > 0.95
    lines = ego_lines(track, pose, half)
    assert lines.left.exists and lines.right.exists
    gone = _visibility(track, _Fade(1.0))
    assert gone.visible_fraction(track.boundaries[0].t, 55.0, 75.0) < 0.1
    lines = ego_lines(track, pose, gone)
    assert not lines.left.exists and not lines.right.exists
    assert ego_lines(track, pose).right.exists


def test_wear_leaves_less_visible_paint_the_more_it_wears(track):
    fractions = [_visibility(track, WearPainter(a)).visible_fraction(track.boundaries[0].t, 5.0, 95.0)
                 for a in (0.0, 0.4, 0.65, 1.0)]
    assert fractions[0] > 0.95
    assert all(a > b for a, b in itertools.pairwise(fractions))


def test_shadow_over_a_line_leaves_it_visible(track):
    """Shadows darken paint and asphalt alike: the ratio test sees through them."""
    shaded = _visibility(track, ShadowPainter(darkness=0.6, per_100m=10.0))
    assert shaded.visible_fraction(track.boundaries[0].t, 155.0, 195.0) > 0.95


def test_no_paint_laid_gives_no_fraction(track):
    assert _visibility(track).visible_fraction(track.boundaries[0].t, 105.0, 145.0) is None
