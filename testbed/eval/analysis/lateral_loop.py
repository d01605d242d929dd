"""The lateral loop's linear analysis with python-control: the scheduled LQR closed around a car model at one
speed and control rate, its closed-loop poles, its gain and phase margins broken at the steering command, and
its responses to a lateral step and a lane change.

A car model is the bicycle model with cornering stiffnesses scaled by `stiffness_scale`, whose wheels reach a
command `lag_s` after the tick that computed it (the steering actuator's lag plus the loop's delay; whole ticks
and the fraction of one are both modelled, as the modified z-transform does). The controller is the one the
loop runs: δ = δ_prev − K_z·[x, δ_prev] with the steering-rate cost, δ = −K·x without, at the state it reads.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from testbed.control.lateral import LqrLateralController, discretise
from testbed.control.lateral_model import LateralModel

if TYPE_CHECKING:
    import control


def _control():
    """python-control, imported on first use: importing it imports pyplot, which chooses a backend."""
    import control

    return control

CAR_STIFFNESS_SCALE = 50.0
"""The simulated car's tyres against the design model's: they barely slip (docs/decisions.md, the steering-rate
cost)."""
MIN_GAIN_MARGIN_DB = 6.0
"""The floor on either gain margin (increase or decrease), 6 dB: the loop tolerates a steering gain off by a
factor of two, which covers a cornering stiffness off by that much at low speed."""
MIN_PHASE_MARGIN_DEG = 30.0
"""The floor on the phase margin, 30°: at the loop's crossover it covers the one-tick delay of a late command."""


@dataclass(frozen=True)
class CarModel:
    """How the car answers a steering command: tyre stiffness against the design model's, and how late (s) the
    wheels reach a command after the tick that computed it, as whole control ticks plus physics steps."""

    name: str
    stiffness_scale: float
    late_ticks: int
    late_physics_steps: int

    def lag_s(self, dt: float, physics_dt: float) -> float:
        return self.late_ticks * dt + self.late_physics_steps * physics_dt

    def lateral_model(self, design: LateralModel) -> LateralModel:
        s = self.stiffness_scale
        return LateralModel(design.wheelbase, design.mass, design.yaw_inertia, design.lf, s * design.cf, s * design.cr)


DESIGN = CarModel("design", 1.0, 0, 0)
"""The model the LQR is designed on: linear tyres, the command applied at once."""
DESIGN_DELAYED = CarModel("design-delayed", 1.0, 1, 1)
"""The design model with the wheels one physics step late and the command one tick late (a CAN chassis that
samples and holds the commands)."""
CAR = CarModel("car", CAR_STIFFNESS_SCALE, 0, 1)
"""The simulated car as measured: tyres 50× stiffer, wheels one physics step late."""
CAR_DELAYED = CarModel("car-delayed", CAR_STIFFNESS_SCALE, 1, 1)
"""The simulated car with the command one tick late as well."""
CAR_MODELS = (DESIGN, DESIGN_DELAYED, CAR, CAR_DELAYED)
FLOORED = (DESIGN_DELAYED, CAR)
"""The models every shipped vehicle and choosable rate must meet the margin floors on."""


def physics_dt(control_hz: float, physics_hz: float) -> float:
    """The physics step of a loop at `control_hz`: the scenario model raises physics to the control rate."""
    return 1.0 / max(physics_hz, control_hz)


def _zoh(a: np.ndarray, b: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
    """(Ad, Bd) over `t`, the identity and zero over no time."""
    if t <= 0.0:
        return np.eye(a.shape[0]), np.zeros_like(b)
    return discretise(a, b, t)


def delayed_plant(model: LateralModel, speed: float, dt: float, lag_s: float) -> control.StateSpace:
    """The car over one tick from the command u_k computed at tick k to the state x_{k+1}, the wheels reaching
    u_k `lag_s` late: states [x, u_{k−1}, …, u_{k−d−1}] (d whole ticks of lag), output x."""
    a, b = model.error_dynamics(speed)
    ticks = lag_s / dt
    whole = math.floor(ticks + 1e-9)
    frac = ticks - whole if ticks - whole > 1e-9 else 0.0
    ad_late, b_late = _zoh(a, b, (1.0 - frac) * dt)
    ad_early, b_early = _zoh(a, b, frac * dt)
    ad, b_old = ad_late @ ad_early, ad_late @ b_early  # u_{k−whole−1} acts first, u_{k−whole} for the rest
    n, held = 4, whole + 1
    big = np.zeros((n + held, n + held))
    big[:n, :n] = ad
    b_in = np.zeros((n + held, 1))
    # column n + j holds u_{k−1−j}; u_{k−whole} is this tick's command when whole = 0
    if whole == 0:
        b_in[:n] += b_late
    else:
        big[:n, n + whole - 1: n + whole] += b_late
    big[:n, n + whole: n + whole + 1] += b_old
    b_in[n, 0] = 1.0
    for j in range(1, held):
        big[n + j, n + j - 1] = 1.0
    c = np.hstack([np.eye(n), np.zeros((n, held))])
    return _control().ss(big, b_in, c, np.zeros((n, 1)), dt)


def controller(gain: np.ndarray, dt: float) -> control.StateSpace:
    """The scheduled law at one speed, from the state x it reads to its command u: the steering-rate law
    u = (1 − k_δ)·u_prev − K_x·x when `gain` has five entries, u = −K·x when four."""
    kx = np.asarray(gain[:4], dtype=float).reshape(1, 4)
    if len(gain) == 4:
        return _control().ss(np.zeros((1, 1)), np.zeros((1, 4)), np.zeros((1, 1)), -kx, dt)
    keep = np.array([[1.0 - float(gain[4])]])
    return _control().ss(keep, -kx, keep, -kx, dt)


@dataclass(frozen=True)
class LoopPoint:
    """The loop at one speed: largest closed-loop pole magnitude, the gain margins up and down (dB, inf where
    no phase crossing limits them), the phase margin (deg) and the crossover frequency (Hz)."""

    speed: float
    max_pole: float
    gain_up_db: float
    gain_down_db: float
    phase_deg: float
    crossover_hz: float

    @property
    def stable(self) -> bool:
        return self.max_pole < 1.0

    def meets(self, gain_db: float = MIN_GAIN_MARGIN_DB, phase_deg: float = MIN_PHASE_MARGIN_DEG) -> bool:
        return self.stable and min(self.gain_up_db, self.gain_down_db) >= gain_db and self.phase_deg >= phase_deg


FREQUENCIES = 1000
"""Points of the frequency grid the margins are read on, log-spaced from 0.01 Hz to the Nyquist rate."""


def loop_margins(speed: float, max_pole: float, loop: control.StateSpace, dt: float) -> LoopPoint:
    """Margins of the discrete loop gain `loop` read on its frequency response (python-control's
    `frequency_response`): gain margins where L crosses the negative real axis, phase margin where |L| = 1."""
    nyquist = math.pi / dt
    omega = np.geomspace(2 * math.pi * 0.01, nyquist, FREQUENCIES)
    resp = _control().frequency_response(loop, omega)
    values = np.asarray(resp.complex).ravel()
    up, down, phase, crossover = math.inf, math.inf, math.inf, 0.0
    for i in np.flatnonzero(np.sign(values.imag[:-1]) != np.sign(values.imag[1:])):
        f = values.imag[i] / (values.imag[i] - values.imag[i + 1])
        at = values[i] + f * (values[i + 1] - values[i])
        if at.real < 0.0:
            db = -20 * math.log10(abs(at.real))
            up, down = (min(up, db), down) if db > 0 else (up, min(down, -db))
    if values.imag[-1] == 0.0 and values.real[-1] < 0.0:  # the Nyquist rate itself
        db = -20 * math.log10(abs(values.real[-1]))
        up, down = (min(up, db), down) if db > 0 else (up, min(down, -db))
    mag = np.abs(values)
    for i in np.flatnonzero(np.sign(mag[:-1] - 1.0) != np.sign(mag[1:] - 1.0)):
        f = (mag[i] - 1.0) / (mag[i] - mag[i + 1])
        at = values[i] + f * (values[i + 1] - values[i])
        margin = 180.0 - abs(math.degrees(math.atan2(at.imag, at.real)))
        if margin < phase:
            phase, crossover = margin, (omega[i] + f * (omega[i + 1] - omega[i])) / (2 * math.pi)
    return LoopPoint(speed, max_pole, up, down, phase, crossover)


class LateralLoop:
    """The lateral LQR of `design` at `control_hz` (steering-rate weight `weight`) closed around `car`."""

    def __init__(self, design: LateralModel, max_steer: float, control_hz: float, weight: float, car: CarModel,
                 physics_hz: float) -> None:
        self.design, self.car, self.dt = design, car, 1.0 / control_hz
        self.controller = LqrLateralController(design, max_steer, self.dt, steer_rate_weight=weight)
        self.plant_model = car.lateral_model(design)
        self.lag_s = car.lag_s(self.dt, physics_dt(control_hz, physics_hz))

    def gain(self, speed: float) -> np.ndarray:
        c = self.controller
        return c.rate_gain(speed) if c.steer_rate_weight > 0.0 else np.array(c.gain(speed))

    def plant(self, speed: float) -> control.StateSpace:
        return delayed_plant(self.plant_model, speed, self.dt, self.lag_s)

    def closed_loop(self, speed: float) -> control.StateSpace:
        """Closed loop from a command disturbance at the plant input to the state: u = C(x) + d."""
        return _control().feedback(self.plant(speed), controller(self.gain(speed), self.dt), sign=1)

    def loop_gain(self, speed: float) -> control.StateSpace:
        """L(z) at the steering command, for negative feedback: the command's way round the loop, negated."""
        return _control().series(self.plant(speed), -controller(self.gain(speed), self.dt))

    def point(self, speed: float) -> LoopPoint:
        poles = self.closed_loop(speed).poles()
        return loop_margins(speed, float(np.abs(poles).max()), self.loop_gain(speed), self.dt)

    def response(self, speed: float, offset: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """t, lateral error and steering command of the loop following a lane centre that moves sideways by
        `offset` (m, one value a tick) on a straight road; the car starts on the old centre."""
        plant = self.plant(speed)
        ctl = controller(self.gain(speed), self.dt)
        x, xc = np.zeros(plant.nstates), np.zeros(ctl.nstates)
        rate = np.diff(offset, prepend=offset[0]) / self.dt
        errors, steers = [], []
        for ref, ref_rate in zip(offset, rate, strict=True):
            read = plant.C @ x - np.array([ref, ref_rate, 0.0, 0.0])
            u = float((ctl.C @ xc + ctl.D @ read)[0])
            xc = ctl.A @ xc + ctl.B @ read
            x = plant.A @ x + plant.B[:, 0] * u
            errors.append(read[0])
            steers.append(u)
        return np.arange(len(offset)) * self.dt, np.array(errors), np.array(steers)


def lane_change_offset(dt: float, width: float = 3.5, duration: float = 4.0, total: float = 10.0) -> np.ndarray:
    """A lane change: the lane centre moves `width` m sideways along a half cosine over `duration` s, a tick
    apart, starting after 1 s."""
    t = np.arange(0.0, total, dt)
    phase = np.clip((t - 1.0) / duration, 0.0, 1.0)
    return width * 0.5 * (1.0 - np.cos(math.pi * phase))


def step_offset(dt: float, size: float = 0.5, total: float = 6.0) -> np.ndarray:
    """A lateral step: the lane centre `size` m to the side from the first tick."""
    return np.full(round(total / dt), size)
