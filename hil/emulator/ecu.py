"""ECU emulator: a drive-by-wire VCU on a CAN bus; its plant is any ChassisPort (the PyBullet car here).

Per step of `dt` (lockstep: on SIM_StepRequest; realtime: every 20 ms of wall time) the VCU
1. latches the command-timeout fault if a command ID has had no verified frame for `command_timeout` s;
2. follows the newest command cycle: all enables set -> self-driving (unless a fault is latched), any clear
   -> standby, which also clears a latched fault once the vehicle stands still;
3. drives the plant: self-driving applies each new cycle once (sample-and-hold), the steering angle clipped
   to `max_steer` and its change to `min(requested, max_steer_rate) * max(elapsed, 20 ms)`; a latched fault
   brakes at `estop_decel` to standstill holding the steering angle; standby coasts;
4. advances the plant by dt and publishes the report messages due at their periods (`hil.link.timing`; lockstep: a
   step of 0 s, the enable handshake's poll, publishes them all), closed in lockstep by SIM_StepDone.
Command frames are verified by a CommandGuard; its bad-frame and foreign-node faults revoke control like a
command timeout does, and so do a pressed chassis e-stop and an injected subsystem fault (`press_estop`,
`inject_fault`: the hardware faults a test drives the bridge with). Frame layout, counters, checksums and the
command time-out come from the chassis profile; truth frames go out only with `truth` (default: the profile's).
A profile that authenticates frames (SecOC) needs its `key` (`hil.link.secoc_key.link_key`).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import can

from hil.emulator.command_guard import CommandGuard, GuardLimits
from hil.link.actuator_map import ActuatorRequest, Gear
from hil.link.codec import ChassisCodec, FrameRejected
from hil.link.profile import ChassisProfile
from hil.link.report_map import DrivingMode, EStopSource, VcuReport
from hil.link.timing import ClockMode, ReportSchedule
from hil.link.wheels import WheelGeometry
from testbed.chassis import ChassisCommand, ChassisPort
from vehicles.params import get_vehicle

STANDSTILL_MPS = 0.01


@dataclass(frozen=True)
class EcuLimits:
    """Actuator limits and time-outs the VCU enforces (rad, rad/s, m/s², s; command_timeout None: the profile's)."""

    max_steer: float = 0.61
    max_steer_rate: float = 1.0
    estop_decel: float = 6.0
    command_timeout: float | None = None
    guard: GuardLimits = field(default_factory=GuardLimits)


def brake_to_standstill(speed: float, decel: float, dt: float) -> float:
    """Acceleration that brakes at `decel` but does not overshoot zero speed within one step of `dt`."""
    if speed <= 0.0:
        return 0.0
    return -min(decel, speed / dt) if dt > 0 else -decel


DEV_CHASSIS_WHEELS = WheelGeometry.of(get_vehicle("dev-chassis"))
"""The rear wheels whose rpm the emulator reports where its profile maps them, unless told others."""


class EcuEmulator:
    """The VCU: verifies commands, enforces limits and time-outs, steps the plant, publishes reports (rear-wheel
    rpm from the plant's speed and yaw rate through `wheels`)."""

    def __init__(
        self,
        bus: can.BusABC,
        plant: ChassisPort,
        limits: EcuLimits = EcuLimits(),
        clock: ClockMode = ClockMode.LOCKSTEP,
        wall_clock: Callable[[], float] = time.monotonic,
        profile: ChassisProfile | None = None,
        truth: bool | None = None,
        key: bytes | None = None,
        wheels: WheelGeometry = DEV_CHASSIS_WHEELS,
    ) -> None:
        self.bus = bus
        self.plant = plant
        self.wheels = wheels
        self.limits = limits
        self.clock = clock
        self._wall_clock = wall_clock
        self.codec = ChassisCodec(profile, key)
        self.profile = self.codec.profile
        self.truth = self.profile.simulation.truth if truth is None else truth
        self.command_timeout_s = limits.command_timeout or self.profile.timing.command_timeout_s
        self.guard = CommandGuard(self.codec, limits.guard)
        self._commands = self.profile.commands.messages
        self._names = {self.codec.frame_id(n): n for n in self._commands}
        self._step_request_id = self.codec.frame_id(self.profile.simulation.step_request)
        self._lock = threading.RLock()
        self._sim_us = 0
        self._latest: dict[str, dict[str, float]] = {}
        self._last_seen: dict[str, float] = {}
        self._fresh: set[str] = set()
        self._applied_at: float | None = None
        self._steer_cmd = 0.0
        self._accel_cmd = 0.0
        self._steer_limited = False
        self._emergency = False
        self._gear = Gear.NO_REQUEST
        self.mode = DrivingMode.STANDBY
        self.command_timeout = False
        self.estop_pressed = False
        self.injected_faults: dict[str, int] = {}
        self.frames_rx = 0
        self.frames_tx = 0
        self.step_requests_rejected = 0
        self._reports = self._report_schedule()
        self._t0 = wall_clock()
        self._notifier: can.Notifier | None = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def _report_schedule(self) -> ReportSchedule:
        p = self.profile
        names = [*p.reports.messages, *(n for n in (p.simulation.truth_position, p.simulation.truth_motion) if n)]
        periods = {name: round(p.report_cycle_s(name) * 1e6) for name in names}
        early = round(p.timing.cycle_s * 1e6) // 2 if self.clock is ClockMode.REALTIME else 0
        return ReportSchedule(periods, early)

    # ------------------------------------------------------------------ running
    def start(self) -> None:
        """Follow the bus (and in realtime mode, step every 20 ms of wall time) until `stop`."""
        self._notifier = can.Notifier(self.bus, [self.handle], timeout=0.05)
        if self.clock is ClockMode.REALTIME:
            self._thread = threading.Thread(target=self._realtime_loop, name="ecu-50hz", daemon=True)
            self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=1.0)
        if self._notifier is not None:
            self._notifier.stop()

    def _realtime_loop(self) -> None:
        deadline = self._wall_clock()
        while not self._stop.is_set():
            deadline += self.profile.timing.cycle_s
            self.step(self.profile.timing.cycle_s)
            delay = deadline - self._wall_clock()
            if delay > 0:
                self._stop.wait(delay)
            else:
                deadline = self._wall_clock()

    # ------------------------------------------------------------------ inputs
    def now(self) -> float:
        """ECU time: plant time in lockstep, wall time in realtime."""
        return self._sim_us / 1e6 if self.clock is ClockMode.LOCKSTEP else self._wall_clock()

    @property
    def faulted(self) -> bool:
        hardware = self.estop_pressed or any(self.injected_faults.values())
        return hardware or self.command_timeout or self.guard.bad_frames or self.guard.foreign_node

    def press_estop(self) -> None:
        """The chassis's own e-stop: brake to standstill and stay out of self-driving until `release_estop`."""
        with self._lock:
            self.estop_pressed = True

    def release_estop(self) -> None:
        with self._lock:
            self.estop_pressed = False

    def inject_fault(self, name: str, level: int) -> None:
        """Report fault `name` (a profile fault name) at `level`; a nonzero level e-stops like any fault."""
        if name not in self.profile.reports.faults:
            raise ValueError(f"profile {self.profile.name} has no fault {name!r}")
        with self._lock:
            self.injected_faults[name] = level
    def handle(self, frame: can.Message) -> None:
        """Process one received frame (the can.Notifier callback)."""
        with self._lock:
            self.frames_rx += 1
            if frame.arbitration_id == self._step_request_id and not frame.is_extended_id:
                self._on_step_request(frame)
                return
            decoded = self.guard.admit(frame, self.now())
            if decoded is not None:
                name = self._names[decoded.frame_id]
                self._latest[name] = dict(decoded.signals)
                self._last_seen[name] = self.now()
                self._fresh.add(name)

    def _on_step_request(self, frame: can.Message) -> None:
        if self.clock is not ClockMode.LOCKSTEP:
            return
        try:
            request = self.codec.decode(frame)
        except FrameRejected:
            self.step_requests_rejected += 1
            return
        dt_us = round(request.signals["StepDt"] * 1e6)
        self.step(dt_us / 1e6)
        self._send(self.profile.simulation.step_done, {"StepCountEcho": request.signals["StepCount"]})

    # ------------------------------------------------------------------ the step
    def step(self, dt: float) -> None:
        """One VCU cycle of `dt` seconds: time-outs, mode, plant command, plant step, reports."""
        with self._lock:
            now = self.now()
            self._check_timeout(now)
            request = self._newest_cycle()
            if request is not None:
                self._follow_enable(request)
            if self.faulted:
                self._estop(dt)
            elif self.mode is DrivingMode.SELF_DRIVING:
                if request is not None:
                    self._apply(request, now)
            else:
                self._accel_cmd = 0.0
                self.plant.send(ChassisCommand(self._steer_cmd, 0.0))
            if dt > 0:
                self.plant.advance(dt)
                if self.clock is ClockMode.LOCKSTEP:
                    self._sim_us += round(dt * 1e6)
            self._publish(poll=dt <= 0)

    def _check_timeout(self, now: float) -> None:
        if self.mode is not DrivingMode.SELF_DRIVING or self.faulted:
            return
        if any(now - self._last_seen.get(n, -1e9) >= self.command_timeout_s for n in self._commands):
            self.command_timeout = True

    def _newest_cycle(self) -> ActuatorRequest | None:
        if not self._fresh or len(self._latest) < len(self._commands):
            return None
        self._fresh.clear()
        return ActuatorRequest.from_signals(*(self._latest[n] for n in self._commands), self.profile)

    def _follow_enable(self, request: ActuatorRequest) -> None:
        if not request.enable:
            if self.faulted and abs(self.plant.read().speed) < STANDSTILL_MPS:
                self.command_timeout = False
                self.guard.clear_faults()
            self.mode = DrivingMode.STANDBY
        elif not self.faulted and self.mode is DrivingMode.STANDBY:
            self.mode = DrivingMode.SELF_DRIVING
            self._applied_at = None

    def _estop(self, dt: float) -> None:
        self.mode = DrivingMode.STANDBY
        self._accel_cmd = brake_to_standstill(self.plant.read().speed, self.limits.estop_decel, dt)
        self.plant.send(ChassisCommand(self._steer_cmd, self._accel_cmd))

    def _apply(self, request: ActuatorRequest, now: float) -> None:
        limit = self.limits.max_steer
        target = min(max(request.steer, -limit), limit)
        if self._applied_at is None:
            self._steer_cmd = self.plant.read().steer
        cycle = self.profile.timing.cycle_s
        elapsed = cycle if self._applied_at is None else max(now - self._applied_at, cycle)
        max_step = min(request.steer_rate, self.limits.max_steer_rate) * elapsed
        steer = min(max(target, self._steer_cmd - max_step), self._steer_cmd + max_step)
        self._steer_limited = abs(steer - request.steer) > 1e-9
        self._steer_cmd = steer
        self._accel_cmd = request.accel
        self._emergency = request.emergency
        self._gear = request.gear
        self._applied_at = now
        self.plant.send(ChassisCommand(steer, request.accel))

    # ------------------------------------------------------------------ outputs
    def estop_source(self) -> EStopSource:
        if self.estop_pressed:
            return EStopSource.CHASSIS_BUTTON
        if self.command_timeout:
            return EStopSource.COMMAND_TIMEOUT
        if self.guard.bad_frames:
            return EStopSource.BAD_FRAMES
        if self.guard.foreign_node:
            return EStopSource.FOREIGN_NODE
        if self.mode is DrivingMode.SELF_DRIVING and self._emergency:
            return EStopSource.EMERGENCY_BRAKE_COMMAND
        return EStopSource.NONE

    def report(self) -> VcuReport:
        state = self.plant.read()
        longitudinal = self.profile.longitudinal
        brake_pct = max(-self._accel_cmd, 0.0) / longitudinal.full_brake_decel * 100.0
        throttle_pct = max(self._accel_cmd, 0.0) / longitudinal.full_throttle_accel * 100.0
        estop = self.estop_source()
        wheel_rpm = self.wheels.rear_rpm(state.speed, state.yaw_rate)
        return VcuReport(
            speed=state.speed,
            accel=state.accel,
            steer=state.steer,
            gear=self._gear,
            enabled=self.mode is DrivingMode.SELF_DRIVING,
            brake_pct=brake_pct,
            emergency_active=estop is not EStopSource.NONE,
            steer_limited=self._steer_limited,
            mode=self.mode,
            estop=estop,
            command_timeout=self.command_timeout,
            bad_frames=self.guard.bad_frames,
            foreign_node=self.guard.foreign_node,
            bad_checksum_count=self.guard.rejected["checksum"],
            bad_counter_count=self.guard.rejected["counter"],
            bad_format_count=self.guard.rejected["format"] + self.guard.rejected["range"],
            true_pose=state.true_pose,
            yaw_rate=state.yaw_rate,
            throttle_pct=throttle_pct,
            faults=dict(self.injected_faults),
            bad_freshness_count=self.guard.rejected["freshness"],
            bad_mac_count=self.guard.rejected["mac"],
            wheel_rpm_rl=wheel_rpm[0],
            wheel_rpm_rr=wheel_rpm[1],
        )

    def _publish(self, poll: bool) -> None:
        t_us = self._sim_us if self.clock is ClockMode.LOCKSTEP else round((self._wall_clock() - self._t0) * 1e6)
        for name, signals in self.report().to_signals(self.profile, truth=self.truth).items():
            if self._reports.due(name, t_us) or poll:
                self._send(name, signals)

    def _send(self, name: str, signals: dict[str, float]) -> None:
        frame = self.codec.encode(name, signals)
        frame.timestamp = time.time()
        self.bus.send(frame)
        self.frames_tx += 1
