import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from testbed.defense.ld_deviation import LdDeviation
from testbed.lane_detection import LaneDetection

LW = 3.5  # lane width from the map


def det(left, right, left_prob=0.9, right_prob=0.9):
    def poly(c0):
        return None if c0 is None else np.array([c0, 0.01, -0.001, 0.0])

    return LaneDetection(0.0, poly(left), poly(right), left_prob, right_prob, (0.0, 40.0))


def test_both_lines_nearer_left_wins():
    # d_left = 1.5 < d_right = 2.0 -> D = 3.5/2 - 1.5 = +0.25 (left of centre)
    assert LdDeviation(0.5).update(det(1.5, -2.0), LW) == pytest.approx(0.25)


def test_both_lines_nearer_right_wins():
    # d_right = 1.4 < d_left = 2.1 -> D = 1.4 - 1.75 = -0.35 (right of centre)
    assert LdDeviation(0.5).update(det(2.1, -1.4), LW) == pytest.approx(-0.35)


def test_one_line_missing():
    # only the right line: D = 1.9 - 1.75 = +0.15; only the left: D = 1.75 - 1.9 = -0.15
    assert LdDeviation(0.5).update(det(None, -1.9), LW) == pytest.approx(0.15)
    assert LdDeviation(0.5).update(det(1.9, None), LW) == pytest.approx(-0.15)


def test_lane_split_far_line_is_ignored():
    # right-turn lane opening: the detected right line follows the turn lane edge at 3.9 m.
    # The poly-width estimate would give D = (3.9 - 1.6) / 2 = 1.15; Alg. 3 uses the near left line:
    # D = 1.75 - 1.6 = +0.15
    assert LdDeviation(0.5).update(det(1.6, -3.9), LW) == pytest.approx(0.15)
    # left-turn lane opening: D = 1.6 - 1.75 = -0.15
    assert LdDeviation(0.5).update(det(4.0, -1.6), LW) == pytest.approx(-0.15)


def test_both_missing_reuses_last_deviation():
    ld_dev = LdDeviation(0.5)
    assert ld_dev.update(det(None, None), LW) is None  # nothing to reuse yet
    assert ld_dev.update(det(1.5, -2.0), LW) == pytest.approx(0.25)
    assert ld_dev.update(det(None, None), LW) == pytest.approx(0.25)
    assert ld_dev.reused
    assert ld_dev.update(LaneDetection.empty(1.0), LW) == pytest.approx(0.25)


def test_nan_and_low_existence_lines_are_invalid():
    ld_dev = LdDeviation(0.5)
    # left is nearer (1.0) but below the existence threshold -> right: D = 2.4 - 1.75 = 0.65
    assert ld_dev.update(det(1.0, -2.4, left_prob=0.3), LW) == pytest.approx(0.65)
    # left has a NaN coefficient -> right: D = 1.5 - 1.75 = -0.25
    nan_left = LaneDetection(
        0.0, np.array([1.0, math.nan, 0.0, 0.0]), np.array([-1.5, 0, 0, 0.0]), 0.9, 0.9, (0.0, 40.0)
    )
    assert ld_dev.update(nan_left, LW) == pytest.approx(-0.25)
    # both invalid (NaN prob, NaN offset) -> last D reused
    assert ld_dev.update(det(math.nan, -1.0, right_prob=math.nan), LW) == pytest.approx(-0.25)
    assert ld_dev.reused


@given(share=st.floats(-0.99, 0.99), width=st.floats(2.7, 4.0))
@settings(max_examples=60, deadline=None)
def test_ideal_detection_recovers_the_deviation(share, width):
    dev = share * width / 2  # inside the lane
    # lines at y = +w/2 - D (left) and y = -w/2 - D (right) for a vehicle D left of the centre
    ld = LaneDetection(
        0.0,
        np.array([width / 2 - dev, 0, 0, 0.0]),
        np.array([-width / 2 - dev, 0, 0, 0.0]),
        0.9,
        0.9,
        (0.0, 40.0),
    )
    assert LdDeviation(0.5).update(ld, width) == pytest.approx(dev, abs=1e-9)


def test_both_lines_give_their_midpoint_whatever_the_map_width():
    # lines painted 3.2 m apart where the map says 3.5: the car 0.1 m left of their midpoint reads +0.1 from both,
    # where the nearer line with the map's width gives 1.75 - 1.5 = +0.25
    assert LdDeviation(0.5, "both").update(det(1.5, -1.7), LW) == pytest.approx(0.1)
    assert LdDeviation(0.5, "nearer").update(det(1.5, -1.7), LW) == pytest.approx(0.25)


def test_one_misread_line_moves_the_midpoint_by_half_its_error():
    # the car 0.2 m left of centre, its left line read 0.4 m too far out
    true, misread = det(1.55, -1.95), det(1.95, -1.95)
    assert LdDeviation(0.5, "both").update(true, LW) == pytest.approx(0.2)
    assert LdDeviation(0.5, "both").update(misread, LW) == pytest.approx(0.0)
    assert LdDeviation(0.5, "nearer").update(misread, LW) == pytest.approx(-0.2)


def test_lines_no_lane_apart_fall_back_to_the_nearer_line():
    # a turn lane opening (the right line on the turn lane's edge, 5.5 m from the left): Alg. 3's nearer line, as in
    # the paper mode, not the midpoint 1.15 m off
    ld_dev = LdDeviation(0.5, "both")
    assert ld_dev.update(det(1.6, -3.9), LW) == pytest.approx(0.15)
    assert ld_dev.side == "left"
    assert ld_dev.update(det(1.6, -1.9), LW) == pytest.approx(0.15)
    assert ld_dev.side == "both"


def test_one_valid_line_is_alg3_in_either_mode():
    for lines in ("nearer", "both"):
        assert LdDeviation(0.5, lines).update(det(None, -1.9), LW) == pytest.approx(0.15)
        assert LdDeviation(0.5, lines).update(det(1.0, -1.9, left_prob=0.3), LW) == pytest.approx(0.15)


@given(share=st.floats(-0.99, 0.99), width=st.floats(2.7, 4.0), paint=st.floats(-0.3, 0.3))
@settings(max_examples=60, deadline=None)
def test_both_lines_recover_the_deviation_when_the_paint_is_not_the_map_width(share, width, paint):
    dev = share * width / 2
    painted = width + paint
    ld = LaneDetection(0.0, np.array([painted / 2 - dev, 0, 0, 0.0]), np.array([-painted / 2 - dev, 0, 0, 0.0]),
                       0.9, 0.9, (0.0, 40.0))
    assert LdDeviation(0.5, "both").update(ld, width) == pytest.approx(dev, abs=1e-9)
