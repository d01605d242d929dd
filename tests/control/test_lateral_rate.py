"""Steering-rate LQR: reduces to the plain LQR as the rate weight vanishes, keeps its continuous meaning across
control rates, stays stable over the schedule (also on a near-kinematic car with a one-step actuator delay), and
keeps the feed-forward equilibrium."""

from __future__ import annotations

import numpy as np
import pytest

from testbed.control.lateral import LqrLateralController, discretise, dlqr, rate_lqr
from testbed.control.lateral_model import LateralModel
from testbed.control.plan import Plan
from tests.control.closed_loop import controller_model

Q = np.diag((0.5, 0.0, 1.0, 0.0))
R = 25.0
RATES = (0.01, 0.025)  # 100 Hz and 40 Hz


def plan(e_y: float = 0.0, e_psi: float = 0.0, kappa: float = 0.0) -> Plan:
    return Plan(e_y, e_psi, kappa, 10.0, 0.0, kappa)


def closed_loop(ad: np.ndarray, b_now: np.ndarray, b_prev: np.ndarray, k: np.ndarray) -> np.ndarray:
    """[x, δ_prev]⁺ of x⁺ = Ad·x + B_now·δ + B_prev·δ_prev under δ = δ_prev − K·[x, δ_prev]."""
    kx, kd = k[None, :4], k[4]
    return np.block([[ad - b_now @ kx, b_prev + b_now * (1.0 - kd)], [-kx, np.array([[1.0 - kd]])]])


def delayed_plant(model: LateralModel, v: float, dt: float, delay: float) -> tuple[np.ndarray, ...]:
    """ZOH model over `dt` whose input acts `delay` s late: (Ad, B for this tick's δ, B for the last tick's δ)."""
    a, b = model.error_dynamics(v)
    ad_late, b_now = discretise(a, b, dt - delay)
    ad_early, b_early = discretise(a, b, delay)
    return ad_late @ ad_early, b_now, ad_late @ b_early


@pytest.mark.parametrize("dt", RATES)
def test_vanishing_rate_weight_gives_the_plain_lqr(dt: float) -> None:
    model = controller_model()
    for v in (2.0, 12.0, 27.0, 38.0):
        ad, bd = discretise(*model.error_dynamics(v), dt)
        plain = dlqr(ad, bd, Q, np.array([[R]])).ravel()
        np.testing.assert_allclose(rate_lqr(ad, bd, Q, R, 1e-9), [*plain, 1.0], rtol=1e-5, atol=1e-8)


@pytest.mark.parametrize("dt", RATES)
def test_rate_design_is_stable_over_the_schedule(dt: float) -> None:
    model = controller_model()
    # the simulated car's tyres barely slip, and its wheels reach their angle one 10 ms physics step late
    stiff = LateralModel(model.wheelbase, model.mass, model.yaw_inertia, model.lf, 50 * model.cf, 50 * model.cr)
    ctl = LqrLateralController(model, 0.6, dt, steer_rate_weight=0.1)
    for v in [*np.arange(1.0, 40.01, 0.5), 13.7, 27.0]:
        ad, bd = discretise(*model.error_dynamics(v), dt)
        assert np.abs(np.linalg.eigvals(closed_loop(ad, bd, np.zeros_like(bd), ctl.rate_gain(v)))).max() < 1.0, v
        assert np.abs(np.linalg.eigvals(closed_loop(*delayed_plant(stiff, v, dt, 0.01), ctl.rate_gain(v)))
                      ).max() < 1.0, v
    # the plain design, which expects the yaw rate to lag the steering by the linear tyres' ~0.17 s, is not
    plain = LqrLateralController(model, 0.6, dt)
    k = np.array([*plain.gain(27.0), 1.0])
    assert np.abs(np.linalg.eigvals(closed_loop(*delayed_plant(stiff, 27.0, dt, 0.01), k))).max() > 1.0


def _slow_poles(dt: float, step_weight: float, v: float) -> np.ndarray:
    """The three slowest closed-loop poles of the rate design, as continuous-time poles (1/s)."""
    ad, bd = discretise(*controller_model().error_dynamics(v), dt)
    k = rate_lqr(ad, bd, Q, R, step_weight)
    poles = np.log(np.linalg.eigvals(closed_loop(ad, bd, np.zeros_like(bd), k)).astype(complex)) / dt
    return np.array(sorted(poles, key=lambda p: (abs(p.real), p.imag))[:3])


@pytest.mark.parametrize("v", [5.0, 27.0])
def test_rate_weight_means_the_same_at_40_and_100_hz(v: float) -> None:
    w = 0.1  # s²: the weight on δ̇², applied per tick as w/dt²
    at_100, at_40 = (_slow_poles(dt, w / dt**2, v) for dt in RATES)
    np.testing.assert_allclose(at_40, at_100, rtol=0.03)
    # a per-tick weight that ignored the period would not: the third pole moves by far more than that
    unscaled = _slow_poles(0.025, w / 0.01**2, v)
    assert np.abs(unscaled[2] - at_100[2]) > 0.1 * np.abs(at_100[2])


def test_rate_controller_holds_the_cornering_equilibrium_and_steps_smoothly() -> None:
    model, v, kappa = controller_model(), 20.0, 1.0 / 300.0
    ctl = LqrLateralController(model, 0.6, 0.025, steer_rate_weight=0.1)
    steer_ss, heading_ss = model.steady_state(v, kappa)
    ctl._last = steer_ss
    on_arc = Plan(0.0, heading_ss, kappa, v, 0.0, kappa)
    assert ctl.update(on_arc, v, yaw_rate=v * kappa) == pytest.approx(steer_ss, abs=1e-8)  # sin e_ψ ≈ e_ψ
    # an offset: the first step is smaller than the plain law's, and it keeps steering back (to the right)
    plain = LqrLateralController(model, 0.6, 0.025)
    ctl.reset()
    first = ctl.update(plan(e_y=0.2), v, yaw_rate=0.0)
    assert 0.0 > first > plain.update(plan(e_y=0.2), v, yaw_rate=0.0)
    assert ctl.update(plan(e_y=0.2), v, yaw_rate=0.0) < first
    # clamped, and held at standstill
    assert ctl.update(plan(e_y=-100.0), v, yaw_rate=0.0) <= 0.6
    held = ctl._last
    assert ctl.update(plan(e_y=1.0), 0.0, yaw_rate=0.0) == held


def test_zero_rate_weight_is_the_plain_controller() -> None:
    model = controller_model()
    a, b = LqrLateralController(model, 0.6, 0.025), LqrLateralController(model, 0.6, 0.025, steer_rate_weight=0.0)
    np.testing.assert_array_equal(a.gains, b.gains)
    for p in (plan(0.3, 0.01, 0.002), plan(-0.1, -0.02, -0.001)):
        assert a.update(p, 27.0, 0.01) == b.update(p, 27.0, 0.01)
