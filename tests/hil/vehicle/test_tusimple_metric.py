"""The TuSimple benchmark's metric on hand-made lanes: exact, shifted within and beyond the threshold (which widens
with the lane's angle and scales with the frame's width), missing and spurious lanes, and the ego-lane choice."""

from __future__ import annotations

import numpy as np
import pytest

from hil.vehicle.tusimple_metric import ABSENT, bench, ego_lanes, line_accuracy, threshold

ROWS = np.arange(240.0, 720.0, 10.0)
LEFT = 600.0 - 0.8 * (ROWS - 240.0)   # leans left towards the bottom
RIGHT = 680.0 + 0.8 * (ROWS - 240.0)


def test_exact_lanes_score_one_without_false_positives_or_negatives():
    s = bench([LEFT, RIGHT], [LEFT, RIGHT], ROWS, 1280)
    assert (s.accuracy, s.fp, s.fn, s.lane_accuracy) == (1.0, 0.0, 0.0, (1.0, 1.0))


def test_a_shift_is_right_within_the_threshold_widened_by_the_angle_and_wrong_beyond():
    vertical = np.full(len(ROWS), 640.0)
    assert threshold(vertical, ROWS, 1280) == pytest.approx(20.0)
    assert threshold(LEFT, ROWS, 1280) == pytest.approx(20.0 / np.cos(np.arctan(0.8)))  # 25.6 px
    assert bench([vertical + 19.0], [vertical], ROWS, 1280).accuracy == 1.0
    assert bench([vertical + 21.0], [vertical], ROWS, 1280).accuracy == 0.0
    assert bench([LEFT + 24.0], [LEFT], ROWS, 1280).accuracy == 1.0
    s = bench([LEFT + 27.0, RIGHT], [LEFT, RIGHT], ROWS, 1280)
    assert (s.accuracy, s.fp, s.fn) == (0.5, 0.5, 0.5)


def test_the_threshold_scales_with_the_frames_width():
    vertical = np.full(len(ROWS), 256.0)
    assert threshold(vertical, ROWS, 512) == pytest.approx(8.0)
    assert bench([vertical + 7.5], [vertical], ROWS, 512).accuracy == 1.0
    assert bench([vertical + 8.5], [vertical], ROWS, 512).accuracy == 0.0


def test_a_missing_lane_is_a_false_negative_and_a_spurious_one_a_false_positive():
    s = bench([LEFT], [LEFT, RIGHT], ROWS, 1280)
    assert (s.accuracy, s.fp, s.fn) == (0.5, 0.0, 0.5)
    s = bench([], [LEFT, RIGHT], ROWS, 1280)
    assert (s.accuracy, s.fp, s.fn) == (0.0, 0.0, 1.0)
    s = bench([LEFT, RIGHT + 200.0], [LEFT], ROWS, 1280)
    assert (s.accuracy, s.fp, s.fn) == (1.0, 0.5, 0.0)


def test_rows_without_a_point_in_both_count_as_right_and_in_one_as_wrong():
    gt = LEFT.copy()
    gt[:12] = ABSENT  # the far 12 of 48 rows unlabelled
    pred = LEFT.copy()
    assert line_accuracy(pred, gt, 20.0) == pytest.approx(36 / 48)
    pred[:12] = ABSENT
    assert line_accuracy(pred, gt, 20.0) == 1.0
    pred[-6:] = ABSENT
    assert line_accuracy(pred, gt, 20.0) == pytest.approx(42 / 48)


def test_the_ego_lanes_are_the_nearest_on_either_side_of_the_bottom_centre():
    far_left = 560.0 - 2.0 * (ROWS - 240.0)
    far_right = 720.0 + 2.0 * (ROWS - 240.0)
    short = np.full(len(ROWS), float(ABSENT))
    short[0] = 640.0
    assert ego_lanes([far_left, RIGHT, short, LEFT, far_right], ROWS, 1280, 720) == (3, 1)
    assert ego_lanes([far_right, RIGHT], ROWS, 1280, 720) == (None, 1)
    right_only = LEFT + 500.0  # meets the bottom row right of the centre
    assert ego_lanes([right_only], ROWS, 1280, 720) == (None, 0)
