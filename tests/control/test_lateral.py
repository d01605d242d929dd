"""LQR lateral controller: closed-loop stability over the speed range, scheduling, feed-forward, fallbacks."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from testbed.control.lateral import LqrLateralController, discretise, gain_schedule
from testbed.control.lateral_model import LateralModel
from testbed.control.plan import Plan
from tests.control.closed_loop import DT, controller_model, shared_lateral


def plan(e_y: float = 0.0, e_psi: float = 0.0, kappa: float = 0.0) -> Plan:
    return Plan(e_y, e_psi, kappa, 10.0, 0.0, kappa)


def closed_loop_with_lag(model: LateralModel, ctl: LqrLateralController, v: float, tau: float) -> np.ndarray:
    """Discrete closed loop of the error model plus a first-order steering lag; the controller sees only
    the four error states (the actuator state is not fed back)."""
    a, b = model.error_dynamics(v)
    aug_a = np.zeros((5, 5))
    aug_a[:4, :4], aug_a[:4, 4:] = a, b
    aug_a[4, 4] = -1.0 / tau
    aug_b = np.zeros((5, 1))
    aug_b[4, 0] = 1.0 / tau
    ad, bd = discretise(aug_a, aug_b, DT)
    k = np.array([[*ctl.gain(v), 0.0]])
    return ad - bd @ k


def test_discrete_closed_loop_is_stable_across_speeds() -> None:
    ctl, model = shared_lateral(), controller_model()
    stiff = LateralModel(model.wheelbase, model.mass, model.yaw_inertia, model.lf, 5e5, 5e5)
    for v in [*np.arange(1.0, 35.01, 0.5), 2.25, 13.7, 33.3]:
        ad, bd = discretise(*model.error_dynamics(v), DT)
        k = np.array([ctl.gain(v)])
        assert np.abs(np.linalg.eigvals(ad - bd @ k)).max() < 1.0, v
        # still stable with a 0.1 s steering lag the design ignored, and with near-kinematic tyres
        assert np.abs(np.linalg.eigvals(closed_loop_with_lag(model, ctl, v, 0.1))).max() < 1.0, v
        assert np.abs(np.linalg.eigvals(closed_loop_with_lag(stiff, ctl, v, 0.1))).max() < 1.0, v


def test_gain_schedule_matches_nodes_and_interpolates_continuously() -> None:
    ctl = shared_lateral()
    for v, row in zip(ctl.speeds, ctl.gains, strict=True):
        np.testing.assert_allclose(ctl.gain(float(v)), row, rtol=1e-12)
    speeds = np.linspace(0.0, 45.0, 4501)
    gains = np.array([ctl.gain(float(v)) for v in speeds])
    # no jumps: consecutive 1 cm/s steps change each gain by a tiny fraction of its range
    span = gains.max(axis=0) - gains.min(axis=0)
    assert (np.abs(np.diff(gains, axis=0)).max(axis=0) <= 0.01 * span + 1e-12).all()
    # midpoints lie between their neighbouring nodes; outside the schedule the end gains hold
    mid = np.array(ctl.gain(10.5))
    lo, hi = np.minimum(ctl.gains[9], ctl.gains[10]), np.maximum(ctl.gains[9], ctl.gains[10])
    assert ((mid >= lo - 1e-12) & (mid <= hi + 1e-12)).all()
    np.testing.assert_allclose(ctl.gain(0.2), ctl.gains[0])
    np.testing.assert_allclose(ctl.gain(60.0), ctl.gains[-1])


def test_steady_state_of_model_is_an_equilibrium_of_its_error_dynamics() -> None:
    model = controller_model()
    for v, kappa in [(5.0, 1 / 60), (10.0, -1 / 60), (27.0, 1 / 600)]:
        steer, e_psi = model.steady_state(v, kappa)
        a, b = model.error_dynamics(v)
        m, iz, lf, lr, cf, cr = model.mass, model.yaw_inertia, model.lf, model.lr, model.cf, model.cr
        # Rajamani's disturbance input: the reference yaw rate v·κ
        b_ref = np.array([0.0, (lr * cr - lf * cf) / (m * v) - v, 0.0, -(lf**2 * cf + lr**2 * cr) / (iz * v)])
        x = np.array([0.0, 0.0, e_psi, 0.0])
        np.testing.assert_allclose(a @ x + b[:, 0] * steer + b_ref * v * kappa, 0.0, atol=1e-9)
    # at walking pace the cornering steer is the kinematic (Ackermann) angle
    steer, e_psi = model.steady_state(0.1, 1 / 60)
    assert steer == pytest.approx(model.wheelbase / 60, rel=1e-3)
    assert e_psi == pytest.approx(-model.lr / 60, rel=1e-2)


def test_feed_forward_holds_the_cornering_equilibrium() -> None:
    ctl, model = shared_lateral(), controller_model()
    v, kappa = 10.0, 1 / 60
    steer_ss, e_psi_ss = model.steady_state(v, kappa)
    steer = ctl.update(plan(0.0, e_psi_ss, kappa), v, yaw_rate=v * kappa)
    assert steer == pytest.approx(steer_ss, rel=0.02)
    kinematic_plus_understeer = model.wheelbase * kappa + model.understeer_gradient * v * v * kappa
    assert steer == pytest.approx(kinematic_plus_understeer, rel=0.02)


def test_sign_convention_steers_back_towards_the_path() -> None:
    ctl = shared_lateral()
    ctl.reset()
    assert ctl.update(plan(e_y=0.5), 10.0, yaw_rate=0.0) < 0.0  # left of the path: steer right
    assert ctl.update(plan(e_y=-0.5), 10.0, yaw_rate=0.0) > 0.0
    assert ctl.update(plan(e_psi=0.1), 10.0, yaw_rate=0.0) < 0.0  # pointing left of the path: steer right


def test_output_is_clamped_and_held_at_standstill() -> None:
    ctl = shared_lateral()
    ctl.reset()
    assert ctl.update(plan(e_y=-50.0), 5.0, yaw_rate=0.0) == ctl.max_steer
    assert ctl.update(plan(e_y=50.0), 5.0, yaw_rate=0.0) == -ctl.max_steer
    assert ctl.update(plan(e_y=0.3), 0.0) == -ctl.max_steer  # standstill: hold the last command
    ctl.reset()
    assert ctl.update(plan(e_y=0.3), 0.0) == 0.0
    for v in (0.05, 0.2, 0.9, 1.0):  # below the schedule: finite, no division by the speed
        assert math.isfinite(ctl.update(plan(e_y=0.3, e_psi=0.05, kappa=0.02), v))


def test_from_vehicle_reads_attributes_and_fills_defaults() -> None:
    sedan = SimpleNamespace(wheelbase=2.85, mass=1800.0, max_steer=0.6)
    ctl = LqrLateralController.from_vehicle(sedan, DT)
    assert ctl.model == LateralModel.from_geometry(2.85, 1800.0)
    np.testing.assert_allclose(ctl.gains, shared_lateral().gains)
    custom = SimpleNamespace(wheelbase=2.0, mass=900.0, max_steer=0.5, lf=0.9, cornering_stiffness_front=5e4)
    model = LateralModel.from_vehicle(custom)
    assert (model.lf, model.lr, model.cf) == (0.9, pytest.approx(1.1), 5e4)
    assert model.cr == pytest.approx(16.0 * 900.0 * 9.81 * 0.9 / 2.0)


@pytest.mark.parametrize("weight", [0.0, 0.03])
def test_a_kept_gain_schedule_is_a_fresh_computation_to_the_bit(weight: float) -> None:
    model = LateralModel.from_geometry(2.85, 1800.0)
    first = LqrLateralController(model, 0.6, DT, steer_rate_weight=weight)
    again = LqrLateralController(model, 0.6, DT, steer_rate_weight=weight)
    fresh = gain_schedule.__wrapped__(model, DT, (0.5, 0.0, 1.0, 0.0), 25.0, weight)
    assert first.gains.tobytes() == again.gains.tobytes() == fresh.tobytes()
    first.gains[3, 0] = 0.0  # a controller's copy: changing it leaves the kept schedule alone
    assert again.gains.tobytes() == LqrLateralController(model, 0.6, DT, steer_rate_weight=weight).gains.tobytes()
    other = LqrLateralController(model, 0.6, 2.0 * DT, steer_rate_weight=weight)
    assert other.gains.tobytes() != fresh.tobytes()
