"""The deviation bound solved on the car: the closed loop's responses to one checked input, identified in
simulation, in the bound's linear program in place of the linear model's.

The car drives the straight `IDENTIFICATION_TRACK` with the scenario's vehicle, rates, controller, localization
noise and defense at one speed, the oracle detector and no traffic, three times: the MSF's own error cancelled
from `SETTLE_S` on (`testbed.attacks.pulse`), then nothing, an offset pulse or a yaw pulse for one camera period
at the first detection `SETTLE_S` + 1 s in with the car at the speed (it starts from rest). Each response is the
true lane deviation of the pulsed run less that of the plain run, per unit of input, from the pulse's tick; the
runs share the seed, so their noise is the same.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from testbed.attacks.pulse import IdentificationPulse
from testbed.control.attack_bound import MeasuredLoop
from testbed.defense.config import DefenseConfig
from testbed.errors import UserError
from testbed.eval.run.runner import SimRun
from testbed.eval.run.scenario import END_MARGIN_M, Scenario
from testbed.traffic.config import TrafficConfig
from tracks.presets import load_track

IDENTIFICATION_TRACK = "urban-straight"
START_S = 20.0
SETTLE_S = 8.0
RAMP_MPS2 = 0.8
"""Less than the planner's acceleration to its cruise speed: the run is long enough to reach it."""
OFFSET_PULSE_M = 0.1
"""Half the default b: the lateral CUSUM does not move; smaller where the steered pose's slew would hold it
(`offset_pulse`)."""
YAW_PULSE_RAD = 0.004
"""Under the default steer_yaw_tol (0.01 rad), so the steering pose's yaw clamp does not act."""


@dataclass(frozen=True)
class Identified:
    """The measured loop and the pulses' time on the plain run's clock (s)."""

    loop: MeasuredLoop
    pulse_time_s: float


def identification_scenario(sc: Scenario, speed: float, horizon_s: float) -> Scenario:
    """`sc`'s vehicle, rates, controller, seed and defense on the straight track at `speed`, long enough for the
    pulse's response over `horizon_s`."""
    return sc.replace(name=f"{sc.name}-identification", track=IDENTIFICATION_TRACK, lane=None, start_s=START_S,
                      speed=speed, duration=max(SETTLE_S + 1.0, speed / RAMP_MPS2) + horizon_s + 1.0,
                      detector="oracle", detector_params={}, localization="msf", attack=None,
                      traffic=TrafficConfig(), stop_at=None)


def offset_pulse(sc: Scenario) -> float:
    """The offset pulse (m): OFFSET_PULSE_M, or half of what `steer_slew` lets the steered pose move in one camera
    period where that is less, so that neither the lateral CUSUM nor the slew acts on it."""
    period = sc.rates.camera_every * sc.rates.control_dt
    return min(OFFSET_PULSE_M, 0.5 * DefenseConfig.from_dict(sc.defense_params).steer_slew * period)


def _deviation(sc: Scenario, pulse: IdentificationPulse) -> tuple[np.ndarray, np.ndarray]:
    sim = SimRun(sc, attack=pulse)
    try:
        rows = sim.run().rows
    finally:
        sim.close()
    return np.array([r.t for r in rows]), np.array([r.phys_dev for r in rows], dtype=float)


def identify(sc: Scenario, speed: float, horizon_s: float) -> Identified:
    """The loop of `sc` at `speed` measured over `horizon_s` (module docstring); UserError when the straight
    track is too short for the run at that speed."""
    run = identification_scenario(sc, speed, horizon_s)
    needed = START_S + speed * run.duration + END_MARGIN_M  # more than the drive: it starts from rest
    track_length = load_track(IDENTIFICATION_TRACK).length
    if needed > track_length:
        raise UserError(f"identifying the loop at {speed:g} m/s needs {needed:.0f} m of straight road, "
                        f"{IDENTIFICATION_TRACK} has {track_length:.0f} m: a lower speed")
    size = offset_pulse(run)
    pulses = [IdentificationPulse(SETTLE_S, SETTLE_S + 1.0, speed, offset, yaw)
              for offset, yaw in ((0.0, 0.0), (size, 0.0), (0.0, YAW_PULSE_RAD))]
    (t, plain), (_, offset), (_, yaw) = (_deviation(run, p) for p in pulses)
    times = {p.pulse_time for p in pulses}
    if len(times) != 1 or None in times:
        raise RuntimeError(f"the identification pulses came at different detections or none: {times}")
    k0 = int(np.searchsorted(t, pulses[0].pulse_time - 1e-9))
    ticks = round(horizon_s * sc.rates.control_hz) + 1
    if k0 + ticks > len(t):
        raise RuntimeError(f"the identification run ended {len(t) - k0} ticks after its pulse, {ticks} needed")
    window = slice(k0, k0 + ticks)
    loop = MeasuredLoop((offset[window] - plain[window]) / size,
                        (yaw[window] - plain[window]) / YAW_PULSE_RAD, sc.rates.camera_every, sc.rates.control_dt)
    return Identified(loop, float(t[k0]))
