"""The largest physical lateral deviation an attacker reaches before LD3 alarms, as a linear program on the
linear closed-loop lateral model, or on the closed loop's responses measured on the car (`MeasuredLoop`).

Model. The loop is the discrete LQR loop on the path-error bicycle model (`LateralModel`, `LqrLateralController`)
at one speed on a straight lane, state z = [e_y, ė_y, e_ψ, ė_ψ, δ_prev]. The attacker moves the pose the
controller steers on by a lateral offset a and a yaw bias ψ. The controller steers only on checked poses:
the MSF pose of each lane detection, carried by odometry until the next one, so (a_i, ψ_i) are held over
camera period i, except that the carried pose moves along its own biased yaw: the offset seen k ticks after
detection i is a_i + k·v·dt·ψ_i. The controller reads the offset as e_y, the yaw bias in e_ψ and in its
kinematic ė_y = v·e_ψ, the gyro's yaw rate unbiased.

Constraints. Per detection the lateral residual D_MSF − D_LD is a_i (D_LD = D_phys) and the heading residual
ψ_MSF − ψ_lines is ψ_i. Neither CUSUM may alarm: for every window of consecutive detections
Σ(|r_i| − b_eff) ≤ τ, written with the CUSUM states S_i ≥ max(0, S_{i−1} + |r_i| − b_eff), S_i ≤ τ and
|r_i| ≤ u_i (an LP whatever the signs of the inputs). b_eff = b + k·σ grants the attacker benign residual
noise σ that happens to cancel its offset.

The bound is max e_y(N) over horizons N up to `horizon_s`: since the loop starts at rest and idling a camera
period shifts any attack by one, the optimum at N is no smaller than at N − camera period, so only the last
camera period's ticks are solved; the bound at `horizon_s` − `CONVERGENCE_LOOKBACK_S` says whether it has
converged.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linprog
from scipy.signal import cont2discrete
from scipy.sparse import coo_matrix

from testbed.control.lateral import LqrLateralController

DEFAULT_HORIZON_S = 10.0
CONVERGENCE_LOOKBACK_S = 2.0
CONVERGENCE_TOL_M = 1e-3
"""The bound has converged when it grows by less than this over the last `CONVERGENCE_LOOKBACK_S`."""


@dataclass(frozen=True)
class Budget:
    """One CUSUM the attacker must keep under its threshold: weight b, threshold τ, benign residual std σ
    (same unit); `b_eff(k)` = b + k·σ. τ = inf: no check. `clamp`: the most of the input that reaches the
    controller (a defense that keeps the pose it steers on within that of the lines); inf: all of it."""

    b: float
    tau: float
    sigma: float = 0.0
    clamp: float = math.inf

    def __post_init__(self) -> None:
        if (self.b < 0 or self.tau < 0 or self.sigma < 0 or not self.clamp > 0
                or math.isnan(self.b + self.tau + self.sigma)):
            raise ValueError(f"CUSUM budget needs b, tau, sigma >= 0 and clamp > 0, got {self}")

    def b_eff(self, k: float) -> float:
        return self.b + k * self.sigma


@dataclass(frozen=True)
class AttackedLoop:
    """Discrete closed loop z⁺ = A z + g_offset·(offset seen) + g_yaw·(yaw bias seen), y = output·z, a lane
    detection every `every` ticks; the offset seen grows by `drift`·ψ per tick after each detection."""

    a: np.ndarray
    g_offset: np.ndarray
    g_yaw: np.ndarray
    output: np.ndarray
    every: int
    dt: float
    drift: float = 0.0

    def responses(self, ticks: int) -> tuple[np.ndarray, np.ndarray]:
        """y at ticks 0..`ticks` − 1 from rest after a unit a (first array) or a unit ψ (second) held over the
        first camera period (the detection at tick 0) and zero after."""
        out = np.zeros((2, ticks))
        for row, (g, drift) in enumerate(((self.g_offset, 0.0), (self.g_yaw, self.drift))):
            z = np.zeros(self.a.shape[0])
            for k in range(ticks):
                out[row, k] = self.output @ z
                u = g + drift * k * self.g_offset if k < self.every else 0.0
                z = self.a @ z + u
        return out[0], out[1]


@dataclass(frozen=True)
class MeasuredLoop:
    """A loop known by its measured responses of y to a unit a and a unit ψ held over one camera period (the
    detection at tick 0), ticks `dt` apart, a detection every `every` ticks: the car's own, where `AttackedLoop`
    is the linear model's."""

    offset_response: np.ndarray
    yaw_response: np.ndarray
    every: int
    dt: float

    def responses(self, ticks: int) -> tuple[np.ndarray, np.ndarray]:
        if ticks > min(len(self.offset_response), len(self.yaw_response)):
            raise ValueError(f"{ticks} ticks asked of responses measured over {len(self.offset_response)}")
        return self.offset_response[:ticks], self.yaw_response[:ticks]


@dataclass(frozen=True)
class BoundResult:
    """The bound (m), the horizon it was solved to (s), the bound `CONVERGENCE_LOOKBACK_S` earlier, whether it
    converged, and the worst attack: a_i (m) and ψ_i (rad) per detection up to the tick where e_y peaks."""

    bound_m: float
    horizon_s: float
    earlier_m: float
    offsets_m: np.ndarray
    yaw_biases: np.ndarray

    @property
    def converged(self) -> bool:
        return self.bound_m - self.earlier_m <= CONVERGENCE_TOL_M


def _solve(ra: np.ndarray, rpsi: np.ndarray, n: int, every: int, lateral: Budget, heading: Budget,
           k_sigma: float, signs: tuple[float, float] | None) -> tuple[float, np.ndarray, np.ndarray]:
    """max e_y at tick `n` under both budgets: (value, a, ψ). Variables per period: a, ψ, u ≥ |a|, w ≥ |ψ|, S, H;
    `signs` (of a, of ψ) confines each input to one sign, None leaves them free."""
    m = max(1, math.ceil(n / every))
    lags = n - every * np.arange(m)
    cost = np.zeros(6 * m)
    cost[:m], cost[m:2 * m] = -ra[lags], -rpsi[lags]
    rows, cols, vals, rhs = [], [], [], []
    r = 0

    def add(terms: list[tuple[int, float]], bound: float) -> None:
        nonlocal r
        for c, v in terms:
            rows.append(r)
            cols.append(c)
            vals.append(v)
        rhs.append(bound)
        r += 1

    budgets = ((0, 2 * m, 4 * m, lateral), (m, 3 * m, 5 * m, heading))
    for x0, u0, s0, budget in budgets:
        for i in range(m):
            add([(x0 + i, 1.0), (u0 + i, -1.0)], 0.0)
            add([(x0 + i, -1.0), (u0 + i, -1.0)], 0.0)
            prev = [(s0 + i - 1, 1.0)] if i else []
            add([(u0 + i, 1.0), (s0 + i, -1.0), *prev], budget.b_eff(k_sigma))
    limits = [None if math.isinf(b.clamp) else b.clamp for b in (lateral, heading)]
    free = [(None if c is None else -c, c) for c in limits for _ in range(m)] if signs is None else \
        [(0, c) if sign > 0 else (None if c is None else -c, 0) for sign, c in zip(signs, limits, strict=True)
         for _ in range(m)]
    bounds = free + [(0, None)] * (2 * m) + [(0, lateral.tau)] * m + [(0, heading.tau)] * m
    a_ub = coo_matrix((vals, (rows, cols)), shape=(r, 6 * m)).tocsr()
    res = linprog(cost, A_ub=a_ub, b_ub=np.array(rhs), bounds=bounds, method="highs")
    if res.status == 3:
        return math.inf, np.full(m, np.nan), np.full(m, np.nan)
    if res.status != 0:
        raise RuntimeError(f"bound LP failed: {res.message}")
    return -float(res.fun), res.x[:m], res.x[m:2 * m]


def deviation_bound(loop: AttackedLoop | MeasuredLoop, lateral: Budget, heading: Budget, k_sigma: float = 1.0,
                    horizon_s: float = DEFAULT_HORIZON_S, one_signed: bool = False) -> BoundResult:
    """The largest |e_y| the loop reaches while both CUSUMs stay at or under τ (module docstring); inf when a
    budget is unlimited in a direction the loop responds to. `one_signed`: each input keeps one sign for the
    whole attack (each of the four sign pairs tried), the attacks that drift the car one way; otherwise the inputs may
    alternate and pump the loop while the CUSUMs fall back between strikes."""
    if horizon_s <= CONVERGENCE_LOOKBACK_S:
        raise ValueError(f"horizon must exceed {CONVERGENCE_LOOKBACK_S} s, got {horizon_s}")
    last = round(horizon_s / loop.dt)
    earlier = round((horizon_s - CONVERGENCE_LOOKBACK_S) / loop.dt)
    ra, rpsi = loop.responses(last + 1)

    patterns = ((1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)) if one_signed else (None,)

    def best(end: int) -> tuple[float, np.ndarray, np.ndarray]:
        return max((_solve(ra, rpsi, n, loop.every, lateral, heading, k_sigma, signs)
                    for n in range(max(1, end - loop.every + 1), end + 1) for signs in patterns), key=lambda s: s[0])

    value, offsets, yaws = best(last)
    return BoundResult(value, last * loop.dt, best(earlier)[0], offsets, yaws)


def lateral_loop(controller: LqrLateralController, speed: float, every: int) -> AttackedLoop:
    """The attacked closed loop of `controller` (its model, gains and period) at `speed` on a straight lane,
    a checked pose every `every` ticks (module docstring)."""
    if speed <= 0 or every < 1:
        raise ValueError(f"speed must be > 0 and every >= 1, got {speed}, {every}")
    dt, v = controller.dt, speed
    a_c, b_c = controller.model.error_dynamics(v)
    ad, bd, *_ = cont2discrete((a_c, b_c, np.eye(4), np.zeros((4, 1))), dt, method="zoh")
    bd = bd[:, 0]
    if controller.steer_rate_weight > 0.0:
        k1, k2, k3, k4, k5 = controller.rate_gain(v)
        held = 1.0 - k5
    else:
        k1, k2, k3, k4 = controller.gain(v)
        held = 0.0
    yaw_gain = k2 * v + k3  # e_ψ enters as itself and in the kinematic ė_y = v·e_ψ
    steer = np.array([-k1, 0.0, -yaw_gain, -k4, held])  # δ = steer·z − k1·offset − yaw_gain·ψ
    to_z = np.append(bd, 1.0)
    a = np.zeros((5, 5))
    a[:4, :4] = ad
    a += np.outer(to_z, steer)
    output = np.zeros(5)
    output[0] = 1.0
    return AttackedLoop(a, to_z * -k1, to_z * -yaw_gain, output, every, dt, drift=v * dt)
