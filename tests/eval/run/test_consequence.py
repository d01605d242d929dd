"""Consequence classification follows the precedence in docs/outputs.md (summary.json, `consequence`)."""

import math

from testbed.eval.run.consequence import ConsequenceMonitor, footprint_corners


def monitor():
    return ConsequenceMonitor(lane_width=3.9, vehicle_width=1.9, vehicle_length=4.9)


def test_straddle_deviation_is_half_the_free_width():
    assert math.isclose(monitor().straddle_dev, 1.0)


def test_first_contact_is_terminal_and_sticks():
    m = monitor()
    assert m.observe(0.2, set(), False, False) is None
    assert m.observe(1.6, {"curb"}, False, False) == "hit_curb"
    assert m.observe(1.7, {"barrier"}, True, True) == "hit_curb"
    assert m.final(stopped_by_response=True, final_dev=0.0) == "hit_curb"


def test_divider_and_drop_off():
    m = monitor()
    assert m.observe(-1.2, {"divider"}, False, False) == "hit_lane_divider"
    m = monitor()
    assert m.observe(2.5, set(), True, False) is None  # off the paved surface without a drop-off: not terminal
    assert m.observe(2.5, set(), True, True) == "fall_off_road"


def test_final_classes():
    m = monitor()
    m.observe(0.3, set(), False, False)
    assert m.final(stopped_by_response=False, final_dev=0.1) == "reach_destination"
    assert m.final(stopped_by_response=True, final_dev=-0.9) == "stop_in_lane"
    assert m.final(stopped_by_response=True, final_dev=1.5) == "stop_with_lane_straddle"
    assert m.final(stopped_by_response=True, final_dev=3.0) == "out_of_lane"
    m.observe(1.2, set(), False, False)
    assert m.final(stopped_by_response=False, final_dev=0.0) == "out_of_lane"


def test_footprint_corners_rotate_with_yaw():
    corners = footprint_corners(0.0, 0.0, math.pi / 2, 4.0, 2.0)
    xs = sorted(round(c[0], 9) for c in corners)
    ys = sorted(round(c[1], 9) for c in corners)
    assert xs == [-1.0, -1.0, 1.0, 1.0]
    assert ys == [-2.0, -2.0, 2.0, 2.0]


def test_crossing_the_centre_line_of_a_two_way_road_is_wrong_way():
    two_way = ConsequenceMonitor(lane_width=3.4, vehicle_width=1.9, vehicle_length=4.9, oncoming_left=True)
    for dev in (0.0, 0.5, 0.9, 0.2):  # a wheel over the centre line (straddle deviation 0.75 m) on the left
        two_way.observe(dev, set(), False, False)
    assert two_way.final(stopped_by_response=False, final_dev=0.2) == "wrong_way"
    right = ConsequenceMonitor(lane_width=3.4, vehicle_width=1.9, vehicle_length=4.9, oncoming_left=True)
    for dev in (0.0, -0.9, 0.0):  # over the right edge line: out of lane, not wrong way
        right.observe(dev, set(), False, False)
    assert right.final(stopped_by_response=False, final_dev=0.0) == "out_of_lane"
    one_way = ConsequenceMonitor(lane_width=3.4, vehicle_width=1.9, vehicle_length=4.9)
    one_way.observe(0.9, set(), False, False)
    assert one_way.final(stopped_by_response=False, final_dev=0.9) == "out_of_lane"
