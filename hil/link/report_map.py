"""The report set in SI units and its mapping onto a profile's report messages (and the emulator's truth frames).

The VCU fills a `VcuReport` and encodes it with `to_signals`; the bridge feeds every verified report frame to
a `ReportFollower`, which renders the latest values as a ChassisState without a pose (the bridge adds its own
odometry pose). Quantities the profile has no signal for are neither sent nor read (yaw rate reads as 0).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import IntEnum

from hil.link.actuator_map import Gear
from hil.link.codec import DecodedFrame
from hil.link.profile import ChassisProfile, SignalRef, default_profile
from testbed.chassis import ChassisState
from tracks.pose import Pose

NO_REPORT = "no-report"


class DrivingMode(IntEnum):
    """The VCU's driving mode by meaning (a profile's [modes] gives wire values); `label` is ChassisState.mode."""

    STANDBY = 0
    SELF_DRIVING = 1
    REMOTE = 2
    MANUAL = 3

    @property
    def label(self) -> str:
        return self.name.lower().replace("_", "-")


class EStopSource(IntEnum):
    """Why the VCU is braking to standstill on its own (a profile's [reports.estop_values] gives wire values)."""

    NONE = 0
    COMMAND_TIMEOUT = 1
    BAD_FRAMES = 2
    FOREIGN_NODE = 3
    EMERGENCY_BRAKE_COMMAND = 4
    CHASSIS_BUTTON = 5


class FaultLevel(IntEnum):
    """Per-subsystem fault level the emulator can report."""

    NO_FAULT = 0
    WARNING = 1
    DEGRADED = 2
    FATAL = 3


@dataclass(frozen=True)
class VcuReport:
    """One report set: motion, actuator status, driving mode, faults, rejection counts, simulation truth.

    `faults` holds further fault values by the profile's fault names (e.g. an injected subsystem fault)."""

    speed: float
    accel: float
    steer: float
    gear: Gear
    enabled: bool
    brake_pct: float
    emergency_active: bool
    steer_limited: bool
    mode: DrivingMode
    estop: EStopSource
    command_timeout: bool
    bad_frames: bool
    foreign_node: bool
    bad_checksum_count: int
    bad_counter_count: int
    bad_format_count: int
    true_pose: Pose | None = None
    yaw_rate: float = 0.0
    throttle_pct: float = 0.0
    faults: dict[str, int] = field(default_factory=dict)
    bad_freshness_count: int = 0
    bad_mac_count: int = 0
    wheel_rpm_rl: float = 0.0
    wheel_rpm_rr: float = 0.0

    def _quantities(self, p: ChassisProfile) -> dict[str, float]:
        estop_values = p.reports.estop_values
        estop = estop_values.get(self.estop.name.lower())
        if estop is None:
            estop = estop_values.get("none", 0) if self.estop is EStopSource.NONE else max(estop_values.values())
        comm = FaultLevel.FATAL if (self.command_timeout or self.bad_frames or self.foreign_node) else 0
        return {
            "speed": self.speed, "accel": self.accel, "steer": p.steering.to_wire(self.steer),
            "yaw_rate": self.yaw_rate, "gear": self.gear.wire(p),
            "mode": p.modes.get(self.mode.name.lower(), p.modes["standby"]), "estop": estop,
            "brake_pct": self.brake_pct, "throttle_pct": self.throttle_pct,
            "emergency_active": int(self.emergency_active), "steer_limited": int(self.steer_limited),
            "comm_fault_level": int(comm), "bad_checksum_count": self.bad_checksum_count,
            "bad_counter_count": self.bad_counter_count, "bad_format_count": self.bad_format_count,
            "bad_freshness_count": self.bad_freshness_count, "bad_mac_count": self.bad_mac_count,
            "wheel_rpm_rl": self.wheel_rpm_rl, "wheel_rpm_rr": self.wheel_rpm_rr,
        }

    def to_signals(self, profile: ChassisProfile | None = None, truth: bool = True) -> dict[str, dict[str, float]]:
        """Signal values per report message in publication order; truth frames only if `truth`, the profile
        names them and a true pose is known."""
        p = profile or default_profile()
        frames: dict[str, dict[str, float]] = {name: {} for name in p.reports.messages}

        def put(ref: SignalRef, value: float) -> None:
            signal = p.message(ref.message).get_signal_by_name(ref.signal)
            lo = signal.minimum if signal.minimum is not None else -math.inf
            hi = signal.maximum if signal.maximum is not None else math.inf
            frames[ref.message][ref.signal] = min(max(value, lo), hi)

        quantities = self._quantities(p)
        for key, ref in p.reports.quantities.items():
            put(ref, quantities[key])
        for ref in p.reports.enabled:
            put(ref, int(self.enabled))
        flags = {"command_timeout": self.command_timeout, "bad_frames": self.bad_frames,
                 "foreign_node": self.foreign_node}
        for name, ref in p.reports.faults.items():
            put(ref, int(flags[name]) if name in flags else self.faults.get(name, 0))
        sim = p.simulation
        if truth and self.true_pose is not None and sim.truth_position and sim.truth_motion:
            yaw = math.remainder(self.true_pose.yaw, math.tau)
            frames[sim.truth_position] = {"TruthX": self.true_pose.x, "TruthY": self.true_pose.y}
            frames[sim.truth_motion] = {"TruthYaw": _clip(yaw, 3.2767), "TruthYawRate": _clip(self.yaw_rate, 3.2767)}
        return frames


def _clip(value: float, bound: float) -> float:
    return min(max(value, -bound), bound)


class ReportFollower:
    """Keeps the latest verified value of every report frame and renders them as a ChassisState."""

    def __init__(self, profile: ChassisProfile | None = None) -> None:
        self.profile = profile or default_profile()
        self._latest: dict[str, dict[str, float]] = {}
        self._mode_names = {v: k for k, v in self.profile.modes.items()}

    def update(self, frame: DecodedFrame) -> None:
        self._latest[frame.name] = dict(frame.signals)

    def value(self, quantity: str) -> float | None:
        """The latest reported value (DBC units) of a report quantity, None before its first report."""
        ref = self.profile.reports.quantities.get(quantity)
        if ref is None or ref.message not in self._latest:
            return None
        return self._latest[ref.message][ref.signal]

    @property
    def mode(self) -> str | None:
        """The reported driving mode by name ("standby", "self_driving", ...), None before the first report."""
        value = self.value("mode")
        if value is None:
            return None
        return self._mode_names.get(int(value), f"mode-{int(value)}")

    def estop(self) -> str | None:
        """The reported e-stop state label when the chassis reports one active, else None."""
        value = self.value("estop")
        if value is None or int(value) == self.profile.reports.estop_values.get("none", 0):
            return None
        return _label(self.profile, self.profile.reports.quantities["estop"], int(value))

    def faults(self) -> tuple[str, ...]:
        """Fault signals reported nonzero: a 1-bit flag by its name, a level as "<name>:<level label>"."""
        names = []
        for name, ref in self.profile.reports.faults.items():
            value = int(self._latest.get(ref.message, {}).get(ref.signal, 0))
            if value:
                length = self.profile.message(ref.message).get_signal_by_name(ref.signal).length
                names.append(name if length == 1 else f"{name}:{_label(self.profile, ref, value)}")
        return tuple(names)

    def truth_pose(self) -> Pose | None:
        """The emulator's true pose, if it publishes one (for measuring only)."""
        sim = self.profile.simulation
        position = self._latest.get(sim.truth_position) if sim.truth_position else None
        motion = self._latest.get(sim.truth_motion) if sim.truth_motion else None
        if position is None or motion is None:
            return None
        return Pose(position["TruthX"], position["TruthY"], motion["TruthYaw"])

    def state(self, t: float, extra_faults: tuple[str, ...] = ()) -> ChassisState:
        steer = self.value("steer")
        mode = self.mode
        return ChassisState(
            t=t,
            speed=self.value("speed") or 0.0,
            steer=self.profile.steering.from_wire(steer) if steer is not None else 0.0,
            accel=self.value("accel") or 0.0,
            true_pose=None,
            yaw_rate=self.value("yaw_rate") or 0.0,
            mode=mode.replace("_", "-") if mode is not None else NO_REPORT,
            faults=self.faults() + extra_faults,
        )


def _label(profile: ChassisProfile, ref: SignalRef, value: int) -> str:
    choices = profile.message(ref.message).get_signal_by_name(ref.signal).choices or {}
    return str(choices[value]).lower() if value in choices else str(value)
