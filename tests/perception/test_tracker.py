import dataclasses
import math

import numpy as np
import pytest

from testbed.defense.ld_deviation import LdDeviation
from testbed.lane_detection import LaneDetection
from testbed.lane_tracker import LaneTracker, TrackerParams, shift_matrix
from tests.perception.lane_scene import LANE_W, CurveEntry, Scene


def d_ld(ld: LaneDetection) -> float | None:
    """Alg. 3's D_LD of one detection, fresh (no memory), nominal lane width."""
    return LdDeviation(0.5).update(ld, LANE_W)


MODES = {"ahead": TrackerParams(), "coefficients": TrackerParams(measure_at=())}
"""The tracker measuring the lines at distances ahead (the default) and measuring their cubics' coefficients."""


@pytest.fixture(params=sorted(MODES))
def params(request) -> TrackerParams:
    return MODES[request.param]


def track(scene: Scene, frames: int, detect, tracker: LaneTracker | TrackerParams):
    """Run `frames` frames; `detect(k, scene)` gives frame k's detection. Returns the tracker and per frame
    (tracked detection, true D_LD from the noiseless lines, detection fed)."""
    tracker = tracker if isinstance(tracker, LaneTracker) else LaneTracker(tracker)
    out = []
    for k in range(frames):
        ld = detect(k, scene)
        tracked = tracker.update(ld, scene.speed, scene.yaw_rate)
        out.append((tracked, d_ld(scene.detect()), ld))
        scene.step()
    return tracker, out


def test_shift_matrix_moves_a_cubic_along_x():
    c = np.array([0.3, -0.02, 0.004, -1e-5])
    x = np.linspace(-3.0, 30.0, 12)
    shifted = shift_matrix(2.5) @ c
    np.testing.assert_allclose(np.polynomial.polynomial.polyval(x, shifted),
                               np.polynomial.polynomial.polyval(x + 2.5, c), atol=1e-12)


@pytest.mark.parametrize("curvature", [0.0, 1 / 80.0, -1 / 150.0])
def test_clean_lines_pass_through_unchanged(curvature, params):
    _, out = track(Scene(curvature, lateral=0.4), 60, lambda k, s: s.detect(), params)
    # measured ahead, an 80-m curve's lines (c2 of the left and right line differ by 3 %) are fitted by the shared
    # cubic about 1 cm off at the car (`test_measured_ahead_the_lines_offset_at_the_car_beats_the_fits_extrapolation`)
    tolerance = 0.01 if not params.measure_at else 0.015
    for tracked, truth, _ in out:
        assert d_ld(tracked) == pytest.approx(truth, abs=tolerance)
        assert tracked.left is not None and tracked.right is not None


def test_noise_on_the_offsets_is_reduced(params):
    rng = np.random.default_rng(3)
    _, out = track(Scene(1 / 200.0, lateral=-0.3), 400, lambda k, s: s.detect(rng, noise=0.10), params)
    raw = np.array([d_ld(ld) - truth for _, truth, ld in out[20:]])
    tracked = np.array([d_ld(t) - truth for t, truth, _ in out[20:]])
    assert np.sqrt(np.mean(tracked**2)) < 0.5 * np.sqrt(np.mean(raw**2))
    assert abs(tracked.mean()) < 0.02


@pytest.mark.parametrize("curvature", [0.0, 1 / 60.0])
def test_coasting_predicts_with_the_odometry(curvature, params):
    """Both lines unseen for 0.8 s while the car drifts across the lane at 0.6 m/s: the tracked D_LD follows
    the drift (odometry and tracked heading), it does not hold the last seen value."""
    scene = Scene(curvature, yaw=math.asin(0.6 / 12.0))
    _, out = track(scene, 56, lambda k, s: s.detect(left=k < 40, right=k < 40), params)
    for tracked, truth, _ in out[40:]:
        assert d_ld(tracked) == pytest.approx(truth, abs=0.02)
    assert out[55][1] - out[39][1] > 0.4  # the car did move


def test_a_lateral_step_shows_in_the_same_frame_with_both_lines(params):
    rng = np.random.default_rng(1)
    scene = Scene(1 / 300.0)
    tracker, _ = track(scene, 40, lambda k, s: s.detect(rng, noise=0.05), params)
    scene.y += 0.6  # the car is moved 0.6 m to the left
    tracked = tracker.update(scene.detect(rng, noise=0.05), scene.speed, scene.yaw_rate)
    assert d_ld(tracked) == pytest.approx(d_ld(scene.detect()), abs=0.08)


def test_a_lateral_step_shows_within_one_frame_with_one_line(params):
    scene = Scene()
    tracker, _ = track(scene, 40, lambda k, s: s.detect(left=False), params)
    scene.y -= 0.5
    first = tracker.update(scene.detect(left=False), scene.speed, scene.yaw_rate)
    scene.step()
    second = tracker.update(scene.detect(left=False), scene.speed, scene.yaw_rate)
    assert d_ld(second) == pytest.approx(d_ld(scene.detect()), abs=0.03)
    assert d_ld(first) > d_ld(second) + 0.3  # the first frame alone is not trusted


def test_a_one_frame_glitch_on_one_line_is_rejected(params):
    scene = Scene()
    tracker, _ = track(scene, 40, lambda k, s: s.detect(), params)
    ld = scene.detect()
    glitch = LaneDetection(ld.timestamp, ld.left - np.array([0.9, 0, 0, 0]), ld.right, 1.0, 1.0, ld.x_range)
    tracked = tracker.update(glitch, scene.speed, scene.yaw_rate)
    assert d_ld(tracked) == pytest.approx(d_ld(ld), abs=0.03)
    assert d_ld(glitch) == pytest.approx(d_ld(ld) + 0.9)  # what LD3 would have used without the tracker


def turned(ld: LaneDetection, shift: float, dc1: float, left: bool = True, right: bool = True) -> LaneDetection:
    """`ld` with its lines moved `shift` m to the left and turned by `dc1` (heading); `left` / `right` False
    drops that line."""
    d = np.array([shift, dc1, 0.0, 0.0])
    return LaneDetection(ld.timestamp, ld.left + d if left else None, ld.right + d if right else None,
                         1.0 if left else 0.0, 1.0 if right else 0.0, ld.x_range)


def test_both_lines_jumping_with_a_turn_are_rejected(params):
    """Both lines read 0.9 m to the left and 0.15 rad turned for one frame (paint misread across the image):
    not the car moving, whose heading to the lane the gyro carries; a jump without the turn is taken."""
    scene = Scene()
    tracker, _ = track(scene, 40, lambda k, s: s.detect(), params)
    glitch = turned(scene.detect(), 0.9, 0.15)
    assert d_ld(tracker.update(glitch, scene.speed, scene.yaw_rate)) == pytest.approx(d_ld(scene.detect()),
                                                                                         abs=0.03)
    scene.step()
    moved = turned(scene.detect(), 0.9, 0.0)
    assert d_ld(tracker.update(moved, scene.speed, scene.yaw_rate)) == pytest.approx(d_ld(moved), abs=0.03)


def test_one_line_jumping_with_a_turn_is_not_confirmed(params):
    """The only seen line reads 1.1 m further out and 0.18 rad turned for several frames (worn paint, the
    detector on the next marking): the tracked lane stays where the odometry carries it."""
    scene = Scene()
    tracker, _ = track(scene, 40, lambda k, s: s.detect(), params)
    for _ in range(6):
        tracked = tracker.update(turned(scene.detect(), 1.1, -0.18, right=False), scene.speed, scene.yaw_rate)
        assert d_ld(tracked) == pytest.approx(d_ld(scene.detect()), abs=0.03)
        scene.step()


def test_a_turned_jump_that_persists_takes_over_after_max_coast(params):
    """Detections that keep disagreeing in place and heading with the tracked lane are not seen lines: once
    none has been taken for `max_coast`, the tracker starts again from what the detector sees (here a car 0.9 m
    further right and turned 0.1 rad to the right, its lines drifting away as that heading implies), so it
    cannot lock itself out."""
    params = dataclasses.replace(params, max_coast=0.5)
    scene = Scene()
    tracker, _ = track(scene, 40, lambda k, s: s.detect(), LaneTracker(params))
    seen = Scene(lateral=-0.9, yaw=-0.1)
    seen.t = scene.t
    outputs = []
    for _ in range(14):
        ld = seen.detect()
        outputs.append((tracker.update(ld, scene.speed, scene.yaw_rate), ld, d_ld(scene.detect())))
        scene.step()
        seen.step()
    # frames 0.05 s apart, the last taken 0.05 s before the first: 0.5 s of coasting is frames 0..9
    for tracked, _, truth in outputs[:10]:
        assert d_ld(tracked) == pytest.approx(truth, abs=0.03)
    for tracked, ld, _ in outputs[10:]:
        assert d_ld(tracked) == pytest.approx(d_ld(ld), abs=0.03)


def test_a_patch_on_one_line_shows_late_and_no_longer_than_it_is_seen(params):
    """The right line is seen 0.4 m further right for 10 frames (a dark patch along it), the left one is fine:
    the tracked right line takes the shift only once it persists (`width_confirm_frames`) and drops it as late."""
    shifted = range(40, 50)

    def detect(k: int, s: Scene) -> LaneDetection:
        ld = s.detect()
        if k not in shifted:
            return ld
        return LaneDetection(ld.timestamp, ld.left, ld.right - np.array([0.4, 0, 0, 0]), 1.0, 1.0, ld.x_range)

    _, out = track(Scene(lateral=-0.3), 70, detect, params)
    true_right = [fed.right[0] + (0.4 if k in shifted else 0.0) for k, (_, _, fed) in enumerate(out)]
    off = [k for k, (tracked, _, _) in enumerate(out) if abs(tracked.right[0] - true_right[k]) > 0.2]
    assert off[0] == shifted.start + params.width_confirm_frames - 1
    assert off[-1] == shifted.stop + params.width_confirm_frames - 2
    assert len(off) == len(shifted)


def test_a_dashed_lines_gaps_are_bridged(params):
    """The left line is seen 0.3 s, unseen 0.3 s (a dashed line's gaps); the car sits nearer the left line."""
    rng = np.random.default_rng(5)
    scene = Scene(1 / 120.0, lateral=0.5)
    _, out = track(scene, 200, lambda k, s: s.detect(rng, noise=0.05, left=(k // 6) % 2 == 0), params)
    for tracked, truth, _ in out[12:]:
        assert tracked.left is not None and tracked.left_prob >= 0.5
        assert d_ld(tracked) == pytest.approx(truth, abs=0.06)


def test_a_missing_line_coasts_for_a_bounded_time(params):
    params = dataclasses.replace(params, max_coast=1.0)
    scene = Scene(lateral=0.3)
    _, out = track(scene, 120, lambda k, s: s.detect(left=not 40 <= k < 100), LaneTracker(params))
    # frames 40.. are 0.05 s apart: the left line is output for 1.0 s after it was last seen at frame 39
    assert all(out[k][0].left is not None for k in range(40, 60))
    assert all(out[k][0].left is None and out[k][0].left_prob == 0.0 for k in range(60, 100))
    assert all(out[k][0].left is not None for k in range(100, 120))
    for tracked, truth, _ in out:
        assert d_ld(tracked) == pytest.approx(truth, abs=0.02)


def test_the_lines_swap_when_the_car_changes_lane(params):
    scene = Scene(yaw=math.asin(1.0 / 12.0))  # 1 m/s to the left: crosses the left line at 1.75 m
    tracker, out = track(scene, 80, lambda k, s: s.detect(), params)
    assert tracker.swaps == 1
    for tracked, truth, _ in out:
        assert tracked.left[0] > -0.05 and tracked.right[0] < 0.05
        assert d_ld(tracked) == pytest.approx(truth, abs=0.03)


def test_coasting_across_a_line_swaps_by_the_prediction(params):
    scene = Scene(yaw=math.asin(1.0 / 12.0))
    tracker, out = track(scene, 40, lambda k, s: s.detect(left=k < 30, right=k < 30), params)
    assert tracker.swaps == 1  # crossed at t = 1.75 s (frame 35) with nothing seen
    for tracked, truth, _ in out[30:]:
        assert d_ld(tracked) == pytest.approx(truth, abs=0.03)


def test_existence_and_reported_variance_weight_the_update(params):
    """A line read 5 cm off moves the tracked one more where it is surer: more probable, or a smaller reported
    variance (the step is inside the gate at each: measured ahead, 10 cm at 1 cm reported is an outlier)."""

    def moved(prob: float, var: float | None) -> float:
        scene = Scene()
        tracker, _ = track(scene, 20, lambda k, s: s.detect(right=False), params)
        ld = scene.detect(right=False)
        off = LaneDetection(ld.timestamp, ld.left + np.array([0.05, 0, 0, 0]), None, prob, 0.0, ld.x_range, var)
        return tracker.update(off, scene.speed, scene.yaw_rate).left[0] - ld.left[0]

    assert moved(0.6, None) < moved(1.0, None)
    assert moved(1.0, 0.2**2) < moved(1.0, None) < moved(1.0, 0.01**2)


def test_the_output_keeps_the_detection_contract(params):
    scene = Scene()
    tracker = LaneTracker(params)
    assert tracker.update(LaneDetection.empty(0.0), 12.0, 0.0) == LaneDetection.empty(0.0)
    ld = scene.detect(right=False)
    tracked = tracker.update(ld, 12.0, 0.0)
    assert tracked.timestamp == ld.timestamp and tracked.x_range == ld.x_range
    assert tracked.right is None and tracked.right_prob == 0.0
    assert tracked.left.shape == (4,) and tracked.left_prob == 1.0
    assert tracked.left_var is None  # the detector reported none
    reported = tracker.update(LaneDetection(0.05, ld.left, None, 1.0, 0.0, ld.x_range, 0.01), 12.0, 0.0)
    assert 0.0 < reported.left_var < 0.01


def test_non_finite_or_improbable_lines_do_not_update(params):
    scene = Scene()
    tracker, _ = track(scene, 20, lambda k, s: s.detect(), params)
    ld = scene.detect()
    bad = LaneDetection(ld.timestamp, np.array([np.nan, 0, 0, 0]), ld.right, 1.0, 0.01, ld.x_range)
    tracked = tracker.update(bad, scene.speed, scene.yaw_rate)
    np.testing.assert_allclose(tracked.left[0], ld.left[0], atol=0.01)
    np.testing.assert_allclose(tracked.right[0], ld.right[0], atol=0.01)


AHEAD = (6.0, 8.0, 10.0, 12.0)


def bent_near(rng: np.random.Generator, read: float = 8.0, spread: float = 0.3):
    """Detections whose fits go wrong towards the car, as a fit extrapolated from anchors read well some metres
    ahead does: each frame's lines bent by e (1 − x/`read`)², e ~ N(0, spread²): off by e at the car, right at
    `read` m and within a quarter of e from 6 to 12 m."""
    def detect(k: int, scene: Scene) -> LaneDetection:
        ld = scene.detect()
        e = rng.normal(0.0, spread)
        bend = e * np.array([1.0, -2.0 / read, 1.0 / read**2, 0.0])
        return LaneDetection(ld.timestamp, ld.left + bend, ld.right + bend, 1.0, 1.0, ld.x_range)
    return detect


@pytest.mark.parametrize("curvature", [0.0, 1 / 100.0])
def test_measured_ahead_the_lines_offset_at_the_car_beats_the_fits_extrapolation(curvature):
    """Fits that go wrong towards the car: measured where they are read well (`measure_at`), the tracked offset at the
    car is under 0.6 of the error of the tracker fed the fits' coefficients; clean lines pass through within 1.5 cm."""
    errors = []
    for params in (TrackerParams(measure_at=()), TrackerParams(measure_at=AHEAD)):
        _, out = track(Scene(curvature, lateral=0.2), 300, bent_near(np.random.default_rng(5)), LaneTracker(params))
        errors.append(np.sqrt(np.mean([(d_ld(t) - truth) ** 2 for t, truth, _ in out[40:]])))
    assert errors[1] < 0.6 * errors[0] and errors[1] < 0.02
    _, clean = track(Scene(curvature, lateral=0.4), 60, lambda k, s: s.detect(),
                     LaneTracker(TrackerParams(measure_at=AHEAD)))
    # on the 100-m curve the lines' shared shape (c2 of the left and right line differ by 3 %) costs the offset
    # measured ahead about 1 cm: the values at 12 m differ from the shared cubic's by 1.4 cm
    assert all(d_ld(t) == pytest.approx(truth, abs=0.015) for t, truth, _ in clean)


def test_measured_ahead_a_lateral_step_of_the_car_still_shows_at_once():
    """Both lines stepping 0.6 m together (the car moved): taken at once with `measure_at` as without it."""
    scene = Scene(0.0)
    tracker = LaneTracker(TrackerParams(measure_at=AHEAD))
    track(scene, 40, lambda k, s: s.detect(), tracker)
    ld = scene.detect()
    step = np.array([0.6, 0.0, 0.0, 0.0])
    tracked = tracker.update(LaneDetection(ld.timestamp, ld.left + step, ld.right + step, 1.0, 1.0, ld.x_range),
                             scene.speed, scene.yaw_rate)
    assert d_ld(tracked) == pytest.approx(d_ld(ld) - 0.6, abs=0.05)


@pytest.mark.parametrize("bad", [dict(measurement_std=(0.1, 0.0, 1e-3, 1e-5)), dict(gate=0.0),
                                 dict(confirm_frames=0), dict(width_confirm_frames=0), dict(max_coast=-1.0),
                                 dict(lateral_std=-0.1), dict(measure_at=(8.0,)), dict(measure_at=(8.0, 6.0)),
                                 dict(measure_at=(-1.0, 6.0)), dict(range_std=0.0),
                                 dict(lane_width_range=(3.0, 2.5)), dict(lane_width_range=(0.0, 4.0))])
def test_bad_parameters_are_refused(bad):
    with pytest.raises(ValueError, match="tracker"):
        TrackerParams(**bad)


def test_a_line_that_would_make_the_lane_too_narrow_or_wide_is_left_out(params):
    """Only the left line seen, then a right line read 1.9 m inside it (a lane 1.6 m wide, the first line read past
    a junction) or 1.6 m outside it (5.1 m): left out, and the right line stays unseen; read where it is, taken."""
    scene = Scene(lateral=0.2)
    tracker, _ = track(scene, 20, lambda k, s: s.detect(right=False), params)
    for shift in (1.9, -1.6):
        ld = scene.detect()
        misread = LaneDetection(ld.timestamp, ld.left, ld.right + np.array([shift, 0, 0, 0]), 1.0, 1.0, ld.x_range)
        tracked = tracker.update(misread, scene.speed, scene.yaw_rate)
        assert tracked.right is None
        assert d_ld(tracked) == pytest.approx(d_ld(scene.detect()), abs=0.03)
        scene.step()
    tracked = tracker.update(scene.detect(), scene.speed, scene.yaw_rate)
    assert tracked.right is not None and tracked.right[0] == pytest.approx(scene.detect().right[0], abs=0.05)


def test_the_width_bound_applies_only_to_a_line_being_taken_up(params):
    """Both lines tracked, then the left one dragged outwards 1.7 m over 2 s (the lane 5.2 m wide, past
    `lane_width_range`) and held there: each line is still taken at every frame, so a line dragged outwards under the
    gate cannot make the tracker drop the other, already tracked."""
    scene = Scene()

    def dragged(k: int, s: Scene) -> LaneDetection:
        ld = s.detect()
        shift = 1.7 * min(1.0, max(0.0, (k - 10) / 40))
        return LaneDetection(ld.timestamp, ld.left + np.array([shift, 0, 0, 0]), ld.right, 1.0, 1.0, ld.x_range)

    tracker = LaneTracker(params)
    for k in range(80):
        fed = dragged(k, scene)
        tracked = tracker.update(fed, scene.speed, scene.yaw_rate)
        assert tracked.left is not None and tracked.right is not None
        assert tracker.lines[0].last_seen == tracker.lines[1].last_seen == fed.timestamp  # both taken
        scene.step()
    assert fed.left[0] - fed.right[0] > 5.0


def test_two_lines_that_are_no_lane_start_no_track(params):
    """Nothing tracked yet, a right line read 1.9 m inside the left (a lane 1.6 m wide) or 1.6 m outside it (5.1 m):
    which of the two is misread cannot be told, so neither starts a track; the true pair, or a line alone, does."""
    scene = Scene(lateral=0.2)
    for shift in (1.9, -1.6):
        tracker = LaneTracker(params)
        ld = scene.detect()
        misread = LaneDetection(ld.timestamp, ld.left, ld.right + np.array([shift, 0, 0, 0]), 1.0, 1.0, ld.x_range)
        tracked = tracker.update(misread, scene.speed, scene.yaw_rate)
        assert tracked.left is None and tracked.right is None and not tracker.started
        scene.step()
        tracked = tracker.update(scene.detect(), scene.speed, scene.yaw_rate)
        assert tracked.left[0] == pytest.approx(scene.detect().left[0], abs=1e-9)
        assert tracked.right[0] == pytest.approx(scene.detect().right[0], abs=1e-9)
    alone = LaneTracker(params)
    ld = scene.detect()
    tracked = alone.update(LaneDetection(ld.timestamp, None, ld.right, 0.0, 1.0, ld.x_range), scene.speed, 0.0)
    assert tracked.right is not None and alone.started


@pytest.mark.parametrize(("curvature_std", "follows"), [(None, True), (1e-5, False)])
def test_measured_ahead_a_curves_start_is_followed(curvature_std, follows):
    """A straight running into a 60-m arc with no clothoid, the car on the lane centre: measured ahead (the default
    `ahead_curvature_std`), the tracked deviation stays within 3.5 cm of the centre and the lines' heading within
    0.019 rad; with the coefficients' curvature random walk (1e-5), which a curve's start outruns, they lag to
    4.4 cm and 0.023 rad."""
    params = TrackerParams() if curvature_std is None else TrackerParams(ahead_curvature_std=curvature_std)
    scene, tracker = CurveEntry(), LaneTracker(params)
    worst_dev = worst_heading = 0.0
    for k in range(160):
        tracked = tracker.update(scene.detect(), scene.speed, scene.yaw_rate)
        if k > 10:
            worst_dev = max(worst_dev, abs(tracked.left[0] + tracked.right[0]) / 2)
            worst_heading = max(worst_heading, abs(tracked.left[1]))
        scene.step()
    assert (worst_dev < 0.035 and worst_heading < 0.019) == follows


def test_a_misread_pair_never_crosses_a_line_far_from_the_car(params):
    """Out of a curve a detector may read the left line turned away and, labelled right, paint that crosses in front
    of the car on its left (Town07's S-bend: c0 +2.57 and +1.19 m, headings -0.30 and -0.62 rad). By offsets at the
    car alone, the car crossing its left line fits them best; the tracked left line is 1.75 m off the car, so it was
    not crossed, and the lines stay where they are."""
    scene = Scene()
    tracker, _ = track(scene, 30, lambda k, s: s.detect(right=False), params)

    def misread(k: int, s: Scene) -> LaneDetection:
        ld = s.detect()
        if k >= 4:
            return ld
        return LaneDetection(ld.timestamp, np.array([ld.left[0] + 0.8, -0.30, 0.0, 0.0]),
                             np.array([1.2, -0.62, 0.0, 0.0]), 0.98, 0.74, ld.x_range)

    tracker, out = track(scene, 30, misread, tracker)
    assert tracker.swaps == 0
    for tracked, truth, _ in out:
        assert tracked.left is not None and tracked.left[0] > 1.0
        assert d_ld(tracked) == pytest.approx(truth, abs=0.05)

