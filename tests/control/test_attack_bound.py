"""The deviation bound's arithmetic on loops whose answer is known in closed form, and on the LQR loop against
the closed forms its own impulse responses give."""

from __future__ import annotations

import math

import numpy as np
import pytest

from testbed.control.attack_bound import AttackedLoop, Budget, MeasuredLoop, deviation_bound, lateral_loop
from testbed.control.lateral import LqrLateralController
from vehicles.params import SEDAN

NONE = Budget(0.0, 0.0)


def lag(p: float, every: int = 1, dt: float = 0.1) -> AttackedLoop:
    """x⁺ = p·x − (1 − p)·offset: a first-order lag that steers the car against the offset it is shown."""
    return AttackedLoop(np.array([[p]]), np.array([-(1.0 - p)]), np.array([0.0]), np.array([1.0]), every, dt)


def test_zero_thresholds_give_zero() -> None:
    assert deviation_bound(lag(0.5), NONE, NONE, horizon_s=5.0).bound_m == pytest.approx(0.0, abs=1e-9)


def test_tau_zero_is_the_steady_state_of_a_equal_b() -> None:
    p, b, horizon = 0.8, 0.2, 5.0
    result = deviation_bound(lag(p), Budget(b, 0.0), NONE, horizon_s=horizon)
    n = round(horizon / 0.1)
    assert result.bound_m == pytest.approx(b * (1.0 - p**n), rel=1e-6)
    assert result.converged
    assert np.allclose(np.abs(result.offsets_m), b)


def test_tau_is_spent_at_the_last_detection_of_a_monotone_lag() -> None:
    # Weights (1 − p)·p^j grow towards the end: every detection at b, and the whole τ at the last one.
    p, b, tau = 0.5, 0.1, 0.4
    result = deviation_bound(lag(p), Budget(b, tau), NONE, horizon_s=5.0)
    assert result.bound_m == pytest.approx(b + (1.0 - p) * tau, rel=1e-6)


def test_noise_margin_widens_b() -> None:
    p, b, sigma, k = 0.5, 0.1, 0.05, 2.0
    result = deviation_bound(lag(p), Budget(b, 0.0, sigma), NONE, k_sigma=k, horizon_s=5.0)
    assert result.bound_m == pytest.approx(b + k * sigma, rel=1e-6)


def test_held_inputs_over_a_camera_period() -> None:
    # A pure delay y_{k+1} = −offset_k, a detection every 3 ticks: the peak is one held offset at b + τ.
    loop = AttackedLoop(np.array([[0.0]]), np.array([-1.0]), np.array([0.0]), np.array([1.0]), 3, 0.1)
    result = deviation_bound(loop, Budget(0.2, 0.3), NONE, horizon_s=3.0)
    assert result.bound_m == pytest.approx(0.5, rel=1e-6)


def test_yaw_bias_carries_the_offset_between_detections() -> None:
    loop = AttackedLoop(np.array([[0.0]]), np.array([1.0]), np.array([0.0]), np.array([1.0]), 3, 0.1, drift=0.5)
    offset, yaw = loop.responses(6)
    assert np.allclose(offset, [0, 1, 1, 1, 0, 0])
    assert np.allclose(yaw, [0, 0, 0.5, 1.0, 0, 0])


def test_unlimited_budget_is_unbounded() -> None:
    assert math.isinf(deviation_bound(lag(0.5), Budget(0.1, math.inf), NONE, horizon_s=5.0).bound_m)


@pytest.fixture(scope="module")
def controller() -> LqrLateralController:
    return LqrLateralController.from_vehicle(SEDAN, 1.0 / 40.0, steer_rate_weight=0.03)


@pytest.mark.parametrize("speed", [12.0, 27.0])
def test_lqr_loop_with_tau_zero_matches_the_impulse_responses(controller: LqrLateralController, speed: float) -> None:
    # τ = 0 leaves |a_i| ≤ b per detection: the best is b·Σ|w| (free signs), b·Σ max(w, 0) one-signed,
    # with w the responses at the peak tick (a lateral-only attack).
    loop = lateral_loop(controller, speed, 2)
    b, horizon = 0.2, 6.0
    n = round(horizon * 40.0)
    offset, _ = loop.responses(n + 1)

    def weights(end: int) -> np.ndarray:
        return offset[end - 2 * np.arange(math.ceil(end / 2))]

    free = max(b * np.abs(weights(e)).sum() for e in (n - 1, n))
    signed = max(b * max(np.clip(weights(e), 0, None).sum(), np.clip(-weights(e), 0, None).sum()) for e in (n - 1, n))
    assert deviation_bound(loop, Budget(b, 0.0), NONE, horizon_s=horizon).bound_m == pytest.approx(free, rel=1e-6)
    assert deviation_bound(loop, Budget(b, 0.0), NONE, horizon_s=horizon, one_signed=True).bound_m == \
        pytest.approx(signed, rel=1e-6)
    assert signed >= b  # the loop settles at e_y = −a: the steady state is reached


def test_lqr_bound_grows_with_speed_and_converges(controller: LqrLateralController) -> None:
    results = [deviation_bound(lateral_loop(controller, v, 2), Budget(0.2, 2.0), Budget(0.03, 0.3), k_sigma=0.0)
               for v in (5.0, 15.0, 30.0)]
    assert all(r.converged for r in results)
    assert results[0].bound_m < results[1].bound_m < results[2].bound_m
    heading_free = deviation_bound(lateral_loop(controller, 15.0, 2), Budget(0.2, 2.0), Budget(0.0, 0.0),
                                   k_sigma=0.0)
    assert heading_free.bound_m < results[1].bound_m


def test_a_measured_loop_gives_the_bound_of_the_loop_it_was_measured_on(controller: LqrLateralController) -> None:
    model = lateral_loop(controller, 15.0, 2)
    measured = MeasuredLoop(*model.responses(round(10.0 / model.dt) + 1), model.every, model.dt)
    lateral, heading = Budget(0.2, 2.0, 0.03), Budget(0.03, 0.3, 0.003, clamp=0.01)
    assert deviation_bound(measured, lateral, heading).bound_m == pytest.approx(
        deviation_bound(model, lateral, heading).bound_m, rel=1e-6)  # the solver's tolerance
    halved = MeasuredLoop(*(r / 2 for r in model.responses(round(10.0 / model.dt) + 1)), model.every, model.dt)
    assert deviation_bound(halved, lateral, heading).bound_m == pytest.approx(
        deviation_bound(model, lateral, heading).bound_m / 2, rel=1e-6)  # linear in the responses
    with pytest.raises(ValueError, match="ticks asked"):
        deviation_bound(measured, lateral, heading, horizon_s=12.0)
