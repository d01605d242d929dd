"""The counter-copying injector against the ECU emulator: what integrity checks and SecOC each let through.

Set-up: the ECU emulator in lockstep with a kinematic plant starting at 10 m/s on y = 0, a lane keeper on the
true pose sending a command cycle every 20 ms, and an injector (`hil.emulator.counter_injector`, +3° of steering) that
sits behind a gateway (the bridge never sees it) and follows a legitimate steer frame with a forged one every
`period_s`. The result counts the forged frames the ECU admitted, names the faults it latched and gives the
plant's sideways offset (y) after `seconds`.

    python -m hil.emulator.injection_study [--profile NAME ...] [--period S ...] [--seconds S]
"""

from __future__ import annotations

import argparse
import math
import sys
import uuid
from collections.abc import Sequence
from dataclasses import dataclass

import can

from hil.emulator.counter_injector import CounterCopyingInjector
from hil.emulator.ecu import EcuEmulator
from hil.emulator.kinematic_plant import KinematicBicyclePlant
from hil.link.actuator_map import ActuatorRequest
from hil.link.codec import ChassisCodec
from hil.link.profile import load_profile
from hil.link.report_map import DrivingMode
from hil.link.secoc_key import link_key
from testbed.chassis import ChassisCommand, ChassisState

SPEED = 10.0
OFFSET = math.radians(3.0)
TICK_S = 0.01
CYCLE_TICKS = 2
STEER_RATE = 1.0
PROFILES = ("ld3-dev", "ld3-dev-secoc")
PERIODS = (None, 0.2, 0.1, 0.02)


def lane_keeper(state: ChassisState) -> ChassisCommand:
    """Hold y = 0 and 10 m/s on the true pose (lateral damping ratio about 0.7 at 10 m/s, 2.7 m wheelbase)."""
    pose = state.true_pose
    steer = -0.05 * pose.y - 0.5 * math.remainder(pose.yaw, math.tau)
    return ChassisCommand(steer, 1.5 * (SPEED - state.speed))


@dataclass(frozen=True)
class InjectionOutcome:
    """One run: forged frames sent and admitted, the ECU's latched faults, the sideways offset at the end (m)."""

    profile: str
    period_s: float | None
    injected: int
    accepted: int
    rejected: dict[str, int]
    faults: tuple[str, ...]
    offset_m: float


def _ecu_faults(ecu: EcuEmulator) -> tuple[str, ...]:
    flags = {"foreign_node": ecu.guard.foreign_node, "bad_frames": ecu.guard.bad_frames,
             "command_timeout": ecu.command_timeout}
    return tuple(name for name, on in flags.items() if on)


def measure_injection(profile_name: str, period_s: float | None, seconds: float = 4.0) -> InjectionOutcome:
    """Drive `seconds` with a forged steer frame after the legitimate one every `period_s` (None: no injector)."""
    profile = load_profile(profile_name)
    key = link_key(profile, "virtual", None)
    bus = can.Bus(interface="virtual", channel=f"injection-{uuid.uuid4().hex}")
    plant = KinematicBicyclePlant(speed=SPEED)
    ecu = EcuEmulator(bus, plant, profile=profile, key=key)
    sender = ChassisCodec(profile, key)
    injector = CounterCopyingInjector(profile, OFFSET)
    injected = accepted = 0
    next_injection = 0.0

    def cycle(cmd: ChassisCommand, enable: bool = True) -> list[can.Message]:
        request = ActuatorRequest.from_command(cmd, enable=enable, steer_rate=STEER_RATE)
        frames = [sender.encode(name, signals) for name, signals in request.to_signals(profile).items()]
        for frame in frames:
            ecu.handle(frame)
        return frames

    try:
        for enable in (False, True):  # the hand-over, one cycle each
            cycle(ChassisCommand(0.0, 0.0), enable=enable)
            ecu.step(CYCLE_TICKS * TICK_S)
        if ecu.mode is not DrivingMode.SELF_DRIVING:
            raise RuntimeError(f"profile {profile_name}: the ECU did not engage")
        for tick in range(round(seconds / TICK_S)):
            t = tick * TICK_S
            if tick % CYCLE_TICKS == 0:
                frames = cycle(lane_keeper(plant.read()))
                if period_s is not None and t >= next_injection - 1e-9:
                    next_injection += period_s
                    steer = next(f for f in frames if f.arbitration_id == injector.frame_id)
                    before = ecu.guard.admitted
                    ecu.handle(injector.forge(steer))
                    injected += 1
                    accepted += ecu.guard.admitted - before
            ecu.step(TICK_S)
    finally:
        bus.shutdown()
    rejected = {reason: n for reason, n in ecu.guard.rejected.items() if n}
    return InjectionOutcome(profile.name, period_s, injected, accepted, rejected, _ecu_faults(ecu),
                            plant.read().true_pose.y)


def _period_label(period_s: float | None) -> str:
    return "none" if period_s is None else f"1 per {period_s * 1e3:.0f} ms"


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m hil.emulator.injection_study", description=__doc__.splitlines()[0])
    parser.add_argument("--profile", action="append", help=f"chassis profile (default: {', '.join(PROFILES)})")
    parser.add_argument("--period", action="append", type=float, help="seconds between forged frames "
                        "(default: none, 0.2, 0.1, 0.02)")
    parser.add_argument("--seconds", type=float, default=4.0)
    args = parser.parse_args(argv)
    periods = args.period or PERIODS
    print("| profile | injector | forged frames admitted by the ECU | rejected (reason: count) | ECU fault "
          f"| sideways offset after {args.seconds:g} s |")
    print("|---|---|---|---|---|---|")
    for name in args.profile or PROFILES:
        for period in periods:
            r = measure_injection(name, period, args.seconds)
            admitted = "–" if period is None else f"{r.accepted} of {r.injected}"
            rejected = ", ".join(f"{k}: {n}" for k, n in r.rejected.items()) or "none"
            print(f"| {r.profile} | {_period_label(period)} | {admitted} | {rejected} | "
                  f"{', '.join(r.faults) or 'none'} | {r.offset_m:.3f} m |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
