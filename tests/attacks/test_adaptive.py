"""The adaptive attack families on hand-built views: what each does to the MSF pose, the GNSS fix or the
detected lines, using the white-box knowledge it is handed (map, defense parameters, rates)."""

import math
from types import SimpleNamespace

import numpy as np
import pytest

from testbed.attacks.base import AttackerView, WhiteBox
from testbed.attacks.burst import BurstAttack, burst_weights
from testbed.attacks.coordinated import CoordinatedShift
from testbed.attacks.gnss_drift import GnssDrift
from testbed.attacks.heading import HeadingBias
from testbed.attacks.offmap import OffMapAttack
from testbed.attacks.zone import ZoneAttack
from testbed.errors import UserError
from testbed.lane_detection import LaneDetection
from testbed.localization.estimate import LocalizationEstimate
from testbed.localization.sensors import GnssFix
from tracks.pose import Pose


class StraightMap:
    """A straight road along +x: an intersection for x in [50, 70), a curve (κ = 0.01) for x in [100, 120)."""

    def is_intersection(self, pose: Pose) -> bool:
        return 50.0 <= pose.x < 70.0

    def lane_curvature(self, pose: Pose, lane=None) -> float:
        return 0.01 if 100.0 <= pose.x < 120.0 else 0.0


def whitebox(b=0.2, tau=2.0, hz=20.0) -> WhiteBox:
    return WhiteBox(StraightMap(), 0, SimpleNamespace(b=b, tau=tau), hz, 100.0,
                    lidar_quality=lambda x, y: 0.3 if x > 80.0 else 0.9)


def drive(attack, seconds: float, speed: float = 10.0, dt: float = 0.01):
    """(t, lateral MSF offset) over a straight drive at `speed` from x = 0 (car on the centreline)."""
    out = []
    for i in range(round(seconds / dt)):
        t = i * dt
        pose = Pose(speed * t, 0.0, 0.0)
        est = attack.tamper_msf(LocalizationEstimate(t, pose, np.eye(3)), AttackerView(t, pose, 0.0, 0.0, speed))
        out.append((t, est.pose.y, est.pose.x - pose.x))
    return np.array(out)


def test_zone_attack_acts_only_from_the_chosen_intersection_and_ramps_out_after_hold():
    attack = ZoneAttack(start=0.0, zone="intersection", index=0, lateral=-2.0, ramp=0.5, hold=1.0)
    attack.know(whitebox())
    trace = drive(attack, 12.0)
    t, y = trace[:, 0], trace[:, 1]
    assert np.all(y[t < 5.0] == 0.0)                      # before the intersection at x = 50 m (t = 5 s)
    assert y[np.searchsorted(t, 5.6)] == pytest.approx(-2.0)  # ramped in within 0.5 s
    assert y[np.searchsorted(t, 7.9)] == pytest.approx(-2.0)  # held 1 s after leaving at t = 7 s
    assert np.all(y[t > 8.6] == 0.0)                      # ramped out after hold
    assert attack.state()["stage"] == "over" and attack.state()["switch_time"] == pytest.approx(5.0)


def test_zone_attack_counts_occurrences_and_can_enter_early_along_the_road():
    attack = ZoneAttack(start=0.0, zone="curve", index=0, lateral=1.0, ramp=0.0, along=20.0)
    attack.know(whitebox())
    trace = drive(attack, 12.0)
    t, y, dx = trace.T
    first = t[np.nonzero(y)[0][0]]
    assert first == pytest.approx(8.0)  # the probe 20 m ahead reaches the curve at x = 100 m when the car is at 80 m
    assert dx[np.nonzero(y)[0][0]] == pytest.approx(20.0)
    second = ZoneAttack(zone="intersection", index=1, lateral=1.0)
    second.know(whitebox())
    assert not np.any(drive(second, 12.0)[:, 1])  # only one intersection on this road


def test_zone_attack_refuses_bad_parameters_and_needs_the_map():
    with pytest.raises(UserError, match="zone must be one of"):
        ZoneAttack(zone="bridge")
    with pytest.raises(UserError, match="index"):
        ZoneAttack(index=-1)
    with pytest.raises(RuntimeError, match="know"):
        drive(ZoneAttack(), 0.05)


def test_offmap_moves_the_pose_far_sideways_in_one_tick_or_a_ramp():
    jump = drive(OffMapAttack(start=1.0, distance=25.0, ramp=0.0), 2.0)
    assert np.all(jump[jump[:, 0] < 1.0, 1] == 0.0) and np.all(jump[jump[:, 0] >= 1.0, 1] == 25.0)
    ramp = drive(OffMapAttack(start=1.0, distance=-20.0, ramp=1.0), 3.0)
    assert ramp[np.searchsorted(ramp[:, 0], 1.5), 1] == pytest.approx(-10.0)


def test_burst_spends_exactly_the_budget_then_holds_under_b():
    for profile in ("flat", "rise", "fall"):
        w = burst_weights(10, profile, 1.6)
        assert w.sum() == pytest.approx(1.6) and np.all(w > 0)
    assert burst_weights(4, "rise", 1.0)[-1] > burst_weights(4, "rise", 1.0)[0]
    attack = BurstAttack(start=1.0, spend=0.5, spread=0.5, profile="flat", sustain=0.5, direction="right")
    attack.know(whitebox(b=0.2, tau=2.0, hz=20.0))
    trace = drive(attack, 3.0)
    per_detection = -trace[(trace[:, 0] >= 1.0) & (np.round(trace[:, 0] * 100) % 5 == 0), 1]
    excess = per_detection[:10] - 0.2
    assert excess.sum() == pytest.approx(0.5 * 2.0) and per_detection[10:] == pytest.approx(0.1)
    s, peak = 0.0, 0.0
    for r in per_detection:  # the defender's CUSUM on a perfect LD that sees the car still centred
        s = max(0.0, s + r - 0.2)
        peak = max(peak, s)
    assert peak == pytest.approx(1.0) and s == 0.0  # spent half of τ = 2, then drained by the sustained 0.1 m


def test_coordinated_shift_keeps_msf_and_lines_consistent():
    attack = CoordinatedShift(start=0.0, rate=1.0, limit=2.0, direction="left")
    view = AttackerView(1.5, Pose(15.0, 0.0, 0.0), 0.0, 0.0, 10.0)
    est = attack.tamper_msf(LocalizationEstimate(1.5, Pose(15.0, 0.0, 0.0), np.eye(3)), view)
    ld = LaneDetection(1.5, np.array([1.75, 0, 0, 0.0]), np.array([-1.75, 0, 0, 0.0]), 1.0, 1.0, (0.0, 30.0))
    moved = attack.tamper_ld(ld, view)
    d_msf = est.pose.y
    d_ld = -(moved.left[0] + moved.right[0]) / 2  # the car's deviation the lines show (centre between them)
    assert d_msf == pytest.approx(1.5) and d_ld == pytest.approx(d_msf)
    assert attack.tamper_msf(LocalizationEstimate(9.0, Pose(0, 0, 0), np.eye(3)),
                             AttackerView(9.0, Pose(0, 0, 0), 0.0, 0.0, 10.0)).pose.y == pytest.approx(2.0)


def test_gnss_drift_waits_for_weak_lidar_then_drifts_linearly():
    attack = GnssDrift(start=0.0, rate=0.5, limit=1.0, lidar_below=0.5, direction="right")
    attack.know(whitebox())
    offsets = []
    for i in range(150):
        t = i * 0.1
        pose = Pose(10.0 * t, 0.0, 0.0)
        fix = attack.spoof_gnss(GnssFix(t, np.array([pose.x, 0.0]), np.eye(2)), AttackerView(t, pose, 0, 0, 10))
        offsets.append(fix.xy[1])
    offsets = np.array(offsets)
    assert np.all(offsets[:81] == 0.0)                 # the LiDAR is strong until x = 80 m (t = 8 s)
    assert offsets[90] == pytest.approx(-0.45, abs=1e-9) and offsets[-1] == pytest.approx(-1.0)
    assert attack.state()["switch_time"] == pytest.approx(8.1)
    assert math.isfinite(attack.describe()["rate"])


def test_heading_bias_turns_the_msf_yaw_and_leaves_its_position():
    attack = HeadingBias(start=1.0, bias=-0.08, ramp=1.0)
    pose = Pose(5.0, 0.2, 0.01)
    early = attack.tamper_msf(LocalizationEstimate(0.5, pose, np.eye(3)), AttackerView(0.5, pose, 0.2, 0.0, 10.0))
    half = attack.tamper_msf(LocalizationEstimate(1.5, pose, np.eye(3)), AttackerView(1.5, pose, 0.2, 0.0, 10.0))
    assert early.pose == pose
    assert (half.pose.x, half.pose.y) == (5.0, 0.2) and half.pose.yaw == pytest.approx(0.01 - 0.04)
    assert attack.state()["stage"] == "ramping"
