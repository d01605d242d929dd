"""The lateral LQR's gains from python-control (`c2d`, `dlqr`) equal the scipy Riccati solve kept here as the
reference, within 1e-12, for every shipped vehicle at the control rates a run can choose, plain and with the
steering-rate cost."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm, solve, solve_discrete_are

from testbed.control.config import ControlConfig
from testbed.control.lateral import LqrLateralController
from testbed.control.lateral_model import LateralModel
from vehicles.params import VEHICLES

Q = (0.5, 0.0, 1.0, 0.0)
R = 25.0


def reference_gains(model: LateralModel, dt: float, weight: float, speeds: np.ndarray) -> np.ndarray:
    """The schedule as scipy solved it: ZOH by the block exponential, the DARE, K = (BᵀXB + R)⁻¹(BᵀXA + Nᵀ)."""
    rows = []
    for v in speeds:
        a, b = model.error_dynamics(float(v))
        block = np.zeros((5, 5))
        block[:4, :4], block[:4, 4:] = a, b
        phi = expm(block * dt)
        ad, bd = np.ascontiguousarray(phi[:4, :4]), np.ascontiguousarray(phi[:4, 4:])
        if weight > 0.0:
            a_aug = np.block([[ad, bd], [np.zeros((1, 4)), np.ones((1, 1))]])
            b_aug = np.vstack([bd, np.ones((1, 1))])
            q = np.zeros((5, 5))
            q[:4, :4], q[4, 4] = np.diag(Q), R
            cross = np.zeros((5, 1))
            cross[4, 0] = R
            r = np.array([[R + weight / dt**2]])
            x = solve_discrete_are(a_aug, b_aug, q, r, s=cross)
            rows.append(solve(b_aug.T @ x @ b_aug + r, b_aug.T @ x @ a_aug + cross.T).ravel())
        else:
            x = solve_discrete_are(ad, bd, np.diag(Q), np.array([[R]]))
            rows.append(solve(bd.T @ x @ bd + R, bd.T @ x @ ad).ravel())
    return np.array(rows)


@pytest.mark.parametrize("vehicle", sorted(VEHICLES))
@pytest.mark.parametrize("hz", [20.0, 40.0, 50.0, 100.0])
@pytest.mark.parametrize("weight", [0.0, ControlConfig().steer_rate_weight])
def test_python_control_gains_equal_the_scipy_solve(vehicle: str, hz: float, weight: float) -> None:
    ctl = LqrLateralController.from_vehicle(VEHICLES[vehicle], 1.0 / hz, steer_rate_weight=weight)
    reference = reference_gains(ctl.model, 1.0 / hz, weight, ctl.speeds)
    assert ctl.gains.shape == reference.shape == (40, 5 if weight > 0.0 else 4)
    np.testing.assert_allclose(ctl.gains, reference, rtol=0.0, atol=1e-12)
