"""The stealthy attacker against the CUSUM it knows: S = max(0, S + |D_MSF − D_LD| − b), alarm S > τ, 20 Hz."""

import numpy as np
import pytest

from testbed.attacks.base import AttackerView
from testbed.attacks.stealthy import CusumKnowledge, StealthyAttack
from testbed.localization.estimate import LocalizationEstimate
from tracks.pose import Pose


def simulate(attack: StealthyAttack, b: float, tau: float, ld_std: float, seed: int, seconds: float = 60.0):
    """100 Hz loop: the car follows the tampered MSF back to the lane centre (first-order, 1 s); LD sees it."""
    rng = np.random.default_rng(seed)
    phys, s, s_max, alarm, peak = 0.0, 0.0, 0.0, False, 0.0
    for i in range(round(seconds * 100)):
        t = i * 0.01
        true = Pose(10.0 * t, phys, 0.0)
        est = attack.tamper_msf(LocalizationEstimate(t, true, np.eye(3) * 1e-4), AttackerView(t, true, phys, 0.0, 10))
        d_msf = est.pose.y
        if i % 5 == 0:
            d_ld = phys + ld_std * rng.normal()
            s = max(0.0, s + abs(d_msf - d_ld) - b)
            s_max = max(s_max, s)
            alarm = alarm or s > tau
        phys -= d_msf * 0.01  # lane centring on the MSF pulls its deviation to 0 with a 1 s lag
        peak = max(peak, abs(phys))
    return phys, s_max, alarm, peak


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_stays_under_tau_while_pushing_the_car(seed):
    attack = StealthyAttack(CusumKnowledge(b=0.6, tau=0.1, ld_noise_std=0.1), start=5.0, direction="left")
    phys, s_max, alarm, _ = simulate(attack, 0.6, 0.1, 0.1, seed)
    assert not alarm and s_max <= 0.1
    assert phys == pytest.approx(-(0.6 - 0.3), abs=0.02)  # car pushed right by b − margin
    assert attack.state()["stage"] == "stealthy"


def test_an_attacker_ignoring_ld_noise_gets_caught():
    attack = StealthyAttack(CusumKnowledge(b=0.6, tau=0.1, ld_noise_std=0.1), start=5.0, margin=0.0)
    _, _, alarm, _ = simulate(attack, 0.6, 0.1, 0.1, seed=0)
    assert alarm


def test_a_spread_burst_spends_tau_evenly_over_its_ticks_then_rides_at_b_minus_the_margin():
    knowledge = CusumKnowledge(b=0.15, tau=4.0, ld_noise_std=0.05)
    attack = StealthyAttack(knowledge, start=0.0, direction="right", spread=1.0)
    pose, offsets = Pose(0, 0, 0), []
    for i in range(40):  # the CUSUM ticks at 20 Hz
        t = 0.05 * i
        attack.tamper_msf(LocalizationEstimate(t, pose, np.eye(3)), AttackerView(t, pose, 0.0, 0.0, 10.0))
        offsets.append(attack.state()["offset"])
    burst = 0.15 - 0.15 + 4.0 / 20  # b − 3σ + τ / (1 s × 20 Hz)
    assert offsets[:19] == pytest.approx([-burst] * 19)
    assert offsets[19] == pytest.approx(-(burst - 1e-3))  # the last burst tick keeps ε under τ
    assert offsets[20:] == pytest.approx([0.0] * 20, abs=1e-12)
    assert attack.s_hat == pytest.approx(4.0 - 1e-3) and attack.describe()["spread"] == 1.0
    _, s_max, alarm, _ = simulate(StealthyAttack(knowledge, start=5.0, spread=1.0), 0.15, 4.0, 0.05, seed=0)
    assert not alarm and s_max <= 4.0


def test_a_zero_spread_is_the_papers_one_tick_burst():
    knowledge = CusumKnowledge(b=0.6, tau=0.1, ld_noise_std=0.1)
    runs = [simulate(StealthyAttack(knowledge, start=5.0, spread=v), 0.6, 0.1, 0.1, seed=3) for v in (0.0, 0.01)]
    assert runs[0] == runs[1]  # 0.01 s rounds to one tick at 20 Hz


def test_idle_before_start_and_bad_parameters():
    attack = StealthyAttack(CusumKnowledge(), start=5.0)
    pose = Pose(0, 0, 0)
    out = attack.tamper_msf(LocalizationEstimate(1.0, pose, np.eye(3)), AttackerView(1.0, pose, 0.0, 0.0, 1.0))
    assert out.pose == pose and attack.state() == {"stage": "idle", "switch_time": None, "offset": 0.0}
    with pytest.raises(ValueError, match="direction"):
        StealthyAttack(CusumKnowledge(), direction="up")
    with pytest.raises(ValueError, match="tau"):
        CusumKnowledge(tau=-1)
    with pytest.raises(ValueError, match="spread"):
        StealthyAttack(CusumKnowledge(), spread=-0.5)
