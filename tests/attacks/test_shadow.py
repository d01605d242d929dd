"""The shadow family on hand-built views: its budget arithmetic, the MSF error it cancels, and the defender's own
CUSUMs fed what it sends (they stay under τ while it spends less than τ, and alarm when it spends more)."""

import math
from types import SimpleNamespace

import numpy as np
import pytest

from testbed.attacks.base import AttackerView, WhiteBox
from testbed.attacks.shadow import ShadowAttack, budgeted_residual
from testbed.defense.attack_detection import Cusum
from testbed.errors import UserError
from testbed.localization.estimate import LocalizationEstimate
from tracks.pose import Pose


class StraightLane:
    """One lane along +x centred on y = 0: the deviation is y (+ left)."""

    def lane_dev(self, pose: Pose, lane=None) -> float:
        return pose.y


DEFENSE = SimpleNamespace(b=0.2, tau=2.0, heading_b=0.03, heading_tau=0.3)


def drive(attack: ShadowAttack, seconds: float, msf_error=(0.05, 0.004), dt: float = 0.025):
    """Rows (t, detection tick, lateral residual, yaw residual) of the tampered MSF against a car held on the
    centreline, the untampered MSF off by `msf_error` (m, rad); control at 40 Hz, detections at 20 Hz."""
    wb = WhiteBox(StraightLane(), 0, DEFENSE, 20.0, 1.0 / dt)
    attack.know(wb)
    rows = []
    for i in range(round(seconds / dt)):
        t = i * dt
        true = Pose(10.0 * t, 0.0, 0.0)
        est = LocalizationEstimate(t, Pose(true.x, msf_error[0], msf_error[1]), np.eye(3))
        out = attack.tamper_msf(est, AttackerView(t, true, 0.0, 0.0, 10.0))
        rows.append((t, wb.detection_tick(t), out.pose.y - true.y, out.pose.yaw - true.yaw))
    return np.array(rows)


def test_the_budget_is_spent_in_even_shares_then_sustained_and_topped_up():
    cusum = Cusum(0.2, 2.0)
    spent = [budgeted_residual(cusum, 0.5, 0.5, 4) for _ in range(6)]
    assert spent[:4] == pytest.approx([0.45] * 4)  # b + 0.5 · 2 / 4 each, the statistic reaching 1.0
    assert spent[4] == pytest.approx(0.1)  # sustain · b: the statistic drains to 0.9
    assert spent[5] == pytest.approx(0.3) and cusum.statistic == pytest.approx(1.0)  # topped up by the room
    assert not cusum.alarmed


def test_the_msf_error_is_cancelled_and_the_checked_residuals_spend_exactly_the_budget():
    attack = ShadowAttack(start=1.0, spend=0.8, sustain=1.0, hspend=0.8, hsustain=1.0, spread=0.5,
                          direction="right")
    rows = drive(attack, 4.0)
    checked = rows[(rows[:, 0] >= 1.0) & (rows[:, 1] == 1)]
    assert checked[:10, 2] == pytest.approx(-(0.2 + 0.8 * 2.0 / 10))  # the MSF's own 0.05 m is not spent
    assert checked[10:, 2] == pytest.approx(-0.2)
    assert checked[:10, 3] == pytest.approx(-(0.03 + 0.8 * 0.3 / 10))
    lateral, heading = Cusum(0.2, 2.0), Cusum(0.03, 0.3)  # the defender's, on a perfect detector
    for _, _, r, rh in checked:
        lateral.update(r)
        heading.update(rh)
    assert lateral.statistic == pytest.approx(1.6) and not lateral.alarmed
    assert heading.statistic == pytest.approx(0.24) and not heading.alarmed
    between = rows[(rows[:, 0] >= 1.0) & (rows[:, 1] == 0)]
    previous = rows[np.flatnonzero((rows[:, 0] >= 1.0) & (rows[:, 1] == 0)) - 1]
    assert between[:, 2] == pytest.approx(previous[:, 2])  # the pose between detections carries the last choice


def test_spending_more_than_the_budget_is_what_the_defender_alarms_on():
    rows = drive(ShadowAttack(start=1.0, spend=1.1, spread=0.5), 4.0, msf_error=(0.0, 0.0))
    lateral = Cusum(0.2, 2.0)
    for r in rows[(rows[:, 0] >= 1.0) & (rows[:, 1] == 1), 2]:
        lateral.update(r)
    assert lateral.alarmed


def test_idle_before_start_and_refuses_bad_parameters():
    rows = drive(ShadowAttack(start=2.0), 1.9)
    assert np.all(rows[:, 2] == pytest.approx(0.05))  # the MSF untouched, its own error and all
    with pytest.raises(UserError):
        ShadowAttack(spend=math.nan)
    with pytest.raises(UserError):
        ShadowAttack(direction="up")
    with pytest.raises(RuntimeError):
        ShadowAttack(start=0.0).tamper_msf(LocalizationEstimate(0.0, Pose(0, 0, 0), np.eye(3)),
                                           AttackerView(0.0, Pose(0, 0, 0), 0.0, 0.0, 10.0))
