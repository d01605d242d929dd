"""CAN chassis bridge: a ChassisPort whose vehicle (ECU emulator or real chassis) sits behind a CAN bus.

The profile says what goes on the wire. A command cycle goes out at every multiple of the profile's cycle, whatever
the loop's rate, carrying the loop's latest command while it is younger than one control period (in realtime one
control period and one cycle; `hil.link.timing`): if the loop stalls, sending stops and the chassis's own command
time-out trips. In realtime a pacer thread sends the cycles on the wall clock, so a long tick of the loop does not
delay them; it starts with the engage's hold command, sent at once. Commands are checked first: a non-finite value
latches bad_command and brakes; finite values are clamped to the profile's limits. Reports are followed through a
can.Notifier and verified by the codec; the pose is the bridge's own kinematic odometry from the reported speed and
steering angle (`hil.link.odometry`), never a simulator frame (truth frames, where an emulator sends them, are only
compared against it: `odometry_error_max_m`, `odometry_error_last_m`).

Faults (`hil.link.faults`) are latched with their chassis time; from then on every command brakes at the profile's
fault_decel, keeping the loop's steering so the car stops in its lane, and `latched_faults()` tells the run to
end as chassis_fault. Lost feedback or a lost ECU leaves the odometry braking at fault_decel from the last
reported speed (what the chassis's own time-out does). A link that dies (the receive thread's bus fails, or a
send fails because the device is gone) latches link_lost; `interrupt` latches interrupted (SIGINT, SIGTERM).
`release` hands control back only at standstill. In realtime, while engaged, each report ID is held to its rate
(`hil.link.report_rate`): faster is a second sender (foreign_sender).
"""

from __future__ import annotations

import math
import threading
import time
from collections import Counter
from collections.abc import Callable

import can

from hil.link.actuator_map import ActuatorRequest
from hil.link.codec import REJECT_REASONS, ChassisCodec, FrameRejected
from hil.link.faults import FaultLatch, one_line
from hil.link.odometry import KinematicOdometry
from hil.link.profile import ChassisProfile, default_profile
from hil.link.report_map import ReportFollower
from hil.link.report_rate import ReportRateGuard
from hil.link.scheduling import realtime_scheduling
from hil.link.timing import ClockMode, CommandCycle
from testbed.chassis import ChassisCommand, ChassisFault, ChassisPort, ChassisState

STANDSTILL_MPS = 0.05
BAD_REPORT_RUN = 3
COMM_FAULTS = ("command_timeout", "bad_frames", "foreign_node")
FEEDBACK_FAULTS = ("report_timeout", "ecu_lost", "link_lost")


def link_died(exc: BaseException) -> bool:
    """True where a bus error says the device or peer is gone (an OSError, or a CanError caused by one)."""
    return isinstance(exc, OSError) or isinstance(exc.__cause__, OSError)


class _Receiver(can.Listener):
    """Hands each received frame to the bridge, and an error of the notifier's receive thread to `on_lost`."""

    def __init__(self, on_frame: Callable[[can.Message], None], on_lost: Callable[[Exception], None]) -> None:
        self.on_frame, self.on_lost = on_frame, on_lost

    def on_message_received(self, msg: can.Message) -> None:
        self.on_frame(msg)

    def on_error(self, exc: Exception) -> None:
        self.on_lost(exc)


class BridgeError(RuntimeError):
    """The VCU did not answer as required (enable handshake) or control cannot be handed back yet."""


class CanChassisBridge(ChassisPort):
    """ChassisPort over a python-can bus in lockstep (simulation) or realtime (hardware) clock mode; `key` is the
    SecOC key of a profile that authenticates frames (`hil.link.secoc_key.link_key`)."""

    def __init__(
        self,
        bus: can.BusABC,
        clock: ClockMode = ClockMode.LOCKSTEP,
        steer_rate: float = 1.0,
        reply_timeout: float = 2.0,
        wall_clock: Callable[[], float] = time.monotonic,
        *,
        profile: ChassisProfile | None = None,
        odometry: KinematicOdometry | None = None,
        key: bytes | None = None,
        pacer_priority: int | None = None,
    ) -> None:
        self.bus = bus
        self.clock = clock
        self.profile = profile or default_profile()
        self.steer_rate = min(steer_rate, self.profile.steering.max_rate)
        self.reply_timeout = reply_timeout
        self._wall_clock = wall_clock
        self.codec = ChassisCodec(self.profile, key)
        self.follower = ReportFollower(self.profile)
        self.odometry = odometry or KinematicOdometry()
        self.fault_latch = FaultLatch()
        sim = self.profile.simulation
        self._step_request_id = self.codec.frame_id(sim.step_request)
        self._step_done_id = self.codec.frame_id(sim.step_done)
        self._foreign_ids = self.profile.command_ids | {self._step_request_id}
        self._report_ids = self.profile.report_ids
        self._followed_ids = self._report_ids | {self._step_done_id} | {
            self.codec.frame_id(name) for name in (sim.truth_position, sim.truth_motion) if name is not None}
        """The frames the bridge reads: the profile's reports and the emulator's step and truth frames (a DBC may
        hold messages the profile does not follow, e.g. PIX's reserved tyre pressures: those are not read)."""
        self._speed_message = self.profile.reports.quantities["speed"].message
        self._cycle_us = round(self.profile.timing.cycle_s * 1e6)
        self._commands = CommandCycle(self._cycle_us, self._cycle_us if clock is ClockMode.REALTIME else 0)
        self._pacer: threading.Thread | None = None
        self.pacer_priority = pacer_priority
        self.pacer_scheduling = "normal"
        """How the realtime pacer thread was scheduled (`hil.link.scheduling`): `SCHED_FIFO N`, or normal (and why)."""
        self._pacer_stop = threading.Event()
        self._cycle_lock = threading.Lock()
        self._listeners: list[can.Listener] = []
        self._tx_lock = threading.Lock()
        self._state_lock = threading.RLock()
        self._last_steer = 0.0
        self._enable = False
        self._engaged = False
        self._t_us = 0
        self._rx_t_us = 0
        self._t0 = wall_clock()
        self._step = 0
        self._done = threading.Condition()
        self._done_echo: int | None = None
        self._ecu_lost = False
        self._feedback_lost = False
        self._speed_seen_us: int | None = None
        self._speed_seen_wall: float | None = None
        self._window: Counter[int] = Counter()
        self._report_rate = self._rate_guards()
        self._reject_run: Counter[int] = Counter()
        self.rejected = dict.fromkeys(REJECT_REASONS, 0)
        self.frames_tx = 0
        self.frames_rx = 0
        self.frames_accepted = 0
        self.foreign_node = False
        self.odometry_error_max_m: float | None = None
        self.odometry_error_last_m: float | None = None
        self._notifier = can.Notifier(bus, [_Receiver(self.handle, self._receive_failed)], timeout=0.05)

    def _rate_guards(self) -> dict[int, ReportRateGuard]:
        """One report-rate guard per report period (the DBC's cycle times), by report ID."""
        cycles = self.profile.report_cycles_by_id()
        guards = {cycle: ReportRateGuard.for_timeout({i for i, c in cycles.items() if c == cycle}, cycle,
                                                     self.profile.timing.report_timeout_s)
                  for cycle in set(cycles.values())}
        return {frame_id: guards[cycle] for frame_id, cycle in cycles.items()}

    # ------------------------------------------------------------------ ChassisPort
    def read(self) -> ChassisState:
        with self._state_lock:
            if self.clock is ClockMode.REALTIME:
                self._check_realtime()
            extra = ("foreign_node",) if self.foreign_node else ()
            extra += tuple(f.kind for f in self.fault_latch.faults if f.kind in FEEDBACK_FAULTS)
            state = self.follower.state(self.time())
            speed = self.odometry.speed if self._feedback_lost else state.speed
            return ChassisState(
                t=state.t,
                speed=speed,
                steer=state.steer,
                accel=state.accel,
                true_pose=self.odometry.pose,
                yaw_rate=state.yaw_rate,
                mode=state.mode,
                faults=tuple(dict.fromkeys((*state.faults, *extra))),
            )

    def send(self, cmd: ChassisCommand) -> None:
        limits, steering = self.profile.longitudinal, self.profile.steering
        if not (math.isfinite(cmd.steer) and math.isfinite(cmd.accel)):
            self._raise("bad_command", f"non-finite command: steer {cmd.steer}, accel {cmd.accel}")
            cmd = ChassisCommand(self._last_steer, -limits.fault_decel)
        steer = min(max(cmd.steer, -steering.max_angle), steering.max_angle)
        accel = min(max(cmd.accel, -limits.max_decel), limits.max_accel)
        if self.fault_latch:
            accel = -limits.fault_decel
        self._last_steer = steer
        self._commands.give(ChassisCommand(steer, accel), self._now_us())

    def advance(self, dt: float) -> None:
        self._check_bus_state()
        self._commands.loop_us = max(round(dt * 1e6), 1)
        if self.clock is ClockMode.REALTIME:
            with self._state_lock:
                self._check_realtime()
            if self._feedback_lost:
                self._coast(round(dt * 1e6))
            self._wait_until(self._t_us + round(dt * 1e6))
            return
        end_us = self._t_us + round(dt * 1e6)
        while self._t_us < end_us:
            step_us = min(end_us - self._t_us, self._cycle_us - self._t_us % self._cycle_us)
            due = self._commands.is_boundary(self._t_us)
            self._exchange(step_us, self._cycle_command(self._t_us) if due else None)
            self._t_us += step_us

    def latched_faults(self) -> tuple[ChassisFault, ...]:
        return self.fault_latch.faults

    def reported(self, quantity: str) -> float | None:
        """The latest reported value (DBC units) of a report quantity of the profile; None before its first."""
        with self._state_lock:
            return self.follower.value(quantity)

    # ------------------------------------------------------------------ public extras
    def time(self) -> float:
        """Chassis time: plant time in lockstep; in realtime, wall time from the epoch the last `engage` set."""
        if self.clock is ClockMode.LOCKSTEP:
            return self._t_us / 1e6
        return self._wall_clock() - self._t0

    def add_listener(self, listener: can.Listener) -> None:
        """Give `listener` every frame this bridge sends (is_rx False) and receives, stamped with chassis time
        in lockstep (so a log of 10 s of plant time spans 10 s) and with wall time in realtime."""
        self._listeners.append(listener)

    def engage(self, timeout: float = 2.0) -> None:
        """Enable handshake: release until standby without a latched fault, then enable until self-driving."""
        self._handshake(False, timeout, lambda: self.follower.mode == "standby" and not self._comm_faults())
        self._handshake(True, timeout, lambda: self.follower.mode == "self_driving")
        if self.clock is ClockMode.REALTIME:
            # report rates are judged from here: before, a set-up that holds the GIL for seconds (building the
            # loop under load) starved the receive thread, and its backlog was taken for a second sender
            self._report_rate = self._rate_guards()
        self._engaged = True
        if self.clock is ClockMode.REALTIME:
            # the run's clock starts here: pacing from construction would replay set-up time as a burst of steps
            self._t0 = self._wall_clock() - self._t_us / 1e6
            self._speed_seen_wall = self._wall_clock()
            # the handshake's hold goes on until the loop's first command: its cycles continue without a gap
            self._commands.give(ChassisCommand(self._last_steer, 0.0), self._now_us())
            self._start_pacer()

    def release(self, timeout: float = 2.0) -> None:
        """Hand control back: release cycles until the VCU reports standby; only at standstill."""
        speed = self.read().speed
        if abs(speed) > STANDSTILL_MPS:
            raise BridgeError(f"refusing to hand back control at {speed:.2f} m/s: not at standstill")
        self._engaged = False
        self._stop_pacer()
        self._handshake(False, timeout, lambda: self.follower.mode == "standby")

    def stop_and_release(self, timeout: float = 10.0) -> None:
        """Brake at fault_decel (steering held) to standstill, then hand control back."""
        deadline = self._wall_clock() + timeout
        while abs(self.read().speed) > STANDSTILL_MPS and not self._ecu_lost:
            if self._wall_clock() > deadline:
                raise BridgeError(f"vehicle not at standstill after {timeout} s of braking")
            self.send(ChassisCommand(self._last_steer, -self.profile.longitudinal.fault_decel))
            self.advance(self.profile.timing.cycle_s)
        if not self._ecu_lost and not self._feedback_lost:
            self.release()

    def sensor_fault(self, kind: str, detail: str) -> None:
        """A sensor the loop depends on failed (a stalled GNSS stream, a camera that stopped): latch `kind`; the
        car brakes in lane and the run ends as chassis_fault."""
        self._raise(kind, detail)

    def interrupt(self, reason: str) -> None:
        """The operator stopped the run (`reason`, e.g. SIGINT): latch interrupted; the car brakes in lane."""
        self._raise("interrupted", f"run interrupted by {reason}")

    def close(self) -> None:
        self._stop_pacer()
        self._notifier.stop()

    # ------------------------------------------------------------------ faults
    def link_lost(self, detail: str) -> None:
        """The bus or its peer is gone: latch link_lost; the odometry coasts as after lost feedback."""
        self._raise("link_lost", detail)
        self._ecu_lost = self._feedback_lost = True

    def _receive_failed(self, exc: Exception) -> None:
        self.link_lost(f"receiving failed: {one_line(exc)}")
        with self._done:
            self._done.notify_all()

    def _raise(self, kind: str, detail: str) -> None:
        self.fault_latch.raise_fault(kind, round(self.time(), 6), detail)

    def _comm_faults(self) -> bool:
        return any(f.split(":")[0] in COMM_FAULTS for f in self.follower.faults())

    def _check_chassis(self) -> None:
        """While engaged: the chassis's e-stop, fault signals and driving mode."""
        if not self._engaged:
            return
        estop = self.follower.estop()
        if estop is not None:
            self._raise("chassis_estop", f"chassis reports e-stop: {estop}")
        faults = self.follower.faults()
        if faults:
            self._raise("chassis_fault", f"chassis reports {', '.join(faults)}")
        mode = self.follower.mode
        if mode != "self_driving":
            self._raise("control_lost", f"chassis left self-driving: mode {mode}")

    def _check_realtime(self) -> None:
        last = self._speed_seen_wall
        timeout = self.profile.timing.report_timeout_s
        if self._engaged and last is not None and self._wall_clock() - last > timeout:
            self._raise("report_timeout", f"no {self._speed_message} for {timeout * 1e3:.0f} ms")
            self._feedback_lost = True
        self._check_chassis()

    def _check_bus_state(self) -> None:
        try:
            state = self.bus.state
        except NotImplementedError:
            return
        if state is can.BusState.ERROR:
            self._raise("bus_error", "bus-off: the controller left the bus")

    # ------------------------------------------------------------------ internals
    def _handshake(self, enable: bool, timeout: float, reached: Callable[[], bool]) -> None:
        self._enable = enable
        deadline = self._wall_clock() + timeout
        idle = ChassisCommand(self._last_steer, 0.0)
        while not reached():
            if self._wall_clock() > deadline or self._ecu_lost:
                state = self.read()
                phase = "enable" if enable else "release"
                raise BridgeError(f"{phase} handshake timed out: mode {state.mode}, faults {state.faults}")
            if self.clock is ClockMode.LOCKSTEP:
                self._exchange(0, idle)
            else:
                self._send_cycle(idle)
                time.sleep(self.profile.timing.cycle_s)

    def _exchange(self, step_us: int, command: ChassisCommand | None) -> None:
        """Lockstep: (command cycle,) SIM_StepRequest, then wait for the SIM_StepDone closing its reports."""
        self._rx_t_us = self._t_us + step_us
        if command is not None:
            self._send_cycle(command)
        if self._ecu_lost:
            self._coast(step_us)
            return
        self._step = (self._step + 1) % 65536
        with self._done:
            self._done_echo = None
        request = self.codec.encode(self.profile.simulation.step_request,
                                    {"StepCount": self._step, "StepDt": step_us / 1e6})
        if not self._transmit(request):  # no clock for the plant: its own command time-out will stop it
            self._ecu_lost = self._feedback_lost = True
            self._coast(step_us)
            return
        with self._done:
            replied = self._done.wait_for(lambda: self._done_echo == self._step or self._ecu_lost,
                                          timeout=self.reply_timeout)
        if not replied:
            self._raise("ecu_lost", f"no step reply from the ECU within {self.reply_timeout} s")
            self._ecu_lost = self._feedback_lost = True
        if self._ecu_lost:
            self._coast(step_us)
            return
        self._close_step(step_us)

    def _close_step(self, step_us: int) -> None:
        """A lockstep report set is complete: count it, follow the odometry, check feedback and the chassis."""
        with self._state_lock:
            end_us = self._t_us + step_us
            if self._window[self.codec.frame_id(self._speed_message)] > 0:
                self._speed_seen_us = end_us
            doubled = sorted(hex(i) for i, n in self._window.items() if n > 1)
            self._window.clear()
            if doubled:
                self._raise_at("foreign_sender", end_us, f"more than one frame per step on report IDs {doubled}")
            timeout_us = round(self.profile.timing.report_timeout_s * 1e6)
            seen = self._speed_seen_us
            if self._engaged and seen is not None and end_us - seen >= timeout_us:
                self._raise_at("report_timeout", end_us, f"no {self._speed_message} for {(end_us - seen) / 1e3:.0f} ms")
                self._feedback_lost = True
            if self._feedback_lost:
                self._coast(step_us)
                return
            self._follow_odometry(step_us / 1e6)
            self._measure_truth()
            if self._engaged:
                self._check_chassis_at(end_us)

    def _raise_at(self, kind: str, t_us: int, detail: str) -> None:
        self.fault_latch.raise_fault(kind, t_us / 1e6, detail)

    def _check_chassis_at(self, t_us: int) -> None:
        saved, self._t_us = self._t_us, t_us
        try:
            self._check_chassis()
        finally:
            self._t_us = saved

    def _follow_odometry(self, dt: float) -> None:
        state = self.follower.state(0.0)
        yaw_rate = state.yaw_rate if "yaw_rate" in self.profile.reports.quantities else None
        self.odometry.update(dt, state.speed, state.steer, yaw_rate)

    def _coast(self, step_us: int) -> None:
        """Feedback lost: the chassis brakes on its own; the odometry assumes fault_decel from the last speed."""
        dt = step_us / 1e6
        speed = max(self.odometry.speed - self.profile.longitudinal.fault_decel * dt, 0.0)
        self.odometry.update(dt, speed, self._last_steer)

    def _measure_truth(self) -> None:
        truth = self.follower.truth_pose()
        if truth is None:
            return
        pose = self.odometry.pose
        error = math.hypot(pose.x - truth.x, pose.y - truth.y)
        self.odometry_error_max_m = max(self.odometry_error_max_m or 0.0, error)
        self.odometry_error_last_m = error

    def _now_us(self) -> int:
        return self._t_us if self.clock is ClockMode.LOCKSTEP else round(self.time() * 1e6)

    def _cycle_command(self, t_us: int) -> ChassisCommand | None:
        """The command a cycle at chassis time `t_us` carries: none without a command younger than one control
        period; braking at fault_decel once a fault is latched."""
        command = self._commands.at(t_us)
        if command is not None and self.fault_latch:
            command = ChassisCommand(command.steer, -self.profile.longitudinal.fault_decel)
        return command

    def _start_pacer(self) -> None:
        self._pacer_stop.clear()
        self._pacer = threading.Thread(target=self._pace, name="bridge-command-cycle", daemon=True)
        self._pacer.start()

    def _stop_pacer(self) -> None:
        self._pacer_stop.set()
        if self._pacer is not None and self._pacer is not threading.current_thread():
            self._pacer.join(timeout=1.0)
        self._pacer = None

    def _pace(self) -> None:
        """Realtime: one command cycle at each cycle boundary of chassis time, the first at once (the engage's hold);
        woken late, it sends at once and goes on at the next boundary after now (boundaries it slept through are
        not sent as a burst)."""
        self.pacer_scheduling = realtime_scheduling(self.pacer_priority)
        boundary_us = self._now_us() // self._cycle_us * self._cycle_us
        while not self._pacer_stop.wait(max(self._t0 + boundary_us / 1e6 - self._wall_clock(), 0.0)):
            command = self._cycle_command(self._now_us())
            if command is not None:
                self._send_cycle(command)
            boundary_us = max(boundary_us + self._cycle_us, (self._now_us() // self._cycle_us + 1) * self._cycle_us)

    def _send_cycle(self, command: ChassisCommand) -> None:
        request = ActuatorRequest.from_command(command, enable=self._enable, steer_rate=self.steer_rate)
        with self._cycle_lock:
            for name, signals in request.to_signals(self.profile).items():
                self._transmit(self.codec.encode(name, signals))

    def _stamp(self, frame: can.Message) -> None:
        """A sent frame's time: in lockstep the start of the step it opens, in realtime the wall clock."""
        frame.timestamp = self._t_us / 1e6 if self.clock is ClockMode.LOCKSTEP else time.time()

    def _transmit(self, frame: can.Message) -> bool:
        """Send one frame; a refusal by the bus latches send_error, a gone device link_lost (the loop learns of
        either) and returns False."""
        with self._tx_lock:
            self._stamp(frame)
            try:
                self.bus.send(frame)
            except (can.CanError, OSError) as exc:
                if link_died(exc):
                    self.link_lost(f"sending 0x{frame.arbitration_id:03X} failed: {exc}")
                else:
                    self._raise("send_error", f"bus refused 0x{frame.arbitration_id:03X}: {exc}")
                return False
            self.frames_tx += 1
            frame.is_rx = False
            for listener in self._listeners:
                listener.on_message_received(frame)
            return True

    def handle(self, frame: can.Message) -> None:
        """Process one received frame (the can.Notifier callback)."""
        self.frames_rx += 1
        if self._listeners:
            if self.clock is ClockMode.LOCKSTEP:
                frame.timestamp = self._rx_t_us / 1e6
            for listener in self._listeners:
                listener.on_message_received(frame)
        if frame.is_error_frame:
            self._raise("bus_error", f"error frame on the bus: {frame}")
            return
        frame_id = frame.arbitration_id
        if frame.is_extended_id:
            return
        if frame_id in self._foreign_ids:
            self.foreign_node = True
            self._raise("foreign_sender", f"frame on command ID 0x{frame_id:03X} from another node")
            return
        if frame_id in self._report_ids:
            self._note_report_arrival(frame_id)
        if frame_id not in self._followed_ids or not self.codec.knows(frame_id):
            return
        try:
            decoded = self.codec.decode(frame)
        except FrameRejected as rejection:
            self.rejected[rejection.reason] += 1
            self._reject_run[frame_id] += 1
            if self._reject_run[frame_id] >= BAD_REPORT_RUN:
                self._raise("bad_frames", f"{BAD_REPORT_RUN} rejected frames in a row on 0x{frame_id:03X}: {rejection}")
            return
        self._reject_run[frame_id] = 0
        self.frames_accepted += 1
        if frame_id == self._step_done_id:
            with self._done:
                self._done_echo = int(decoded.signals["StepCountEcho"])
                self._done.notify_all()
            return
        with self._state_lock:
            self.follower.update(decoded)
            if decoded.name == self._speed_message and self.clock is ClockMode.REALTIME:
                now = self._wall_clock()
                last = self._speed_seen_wall
                if self._engaged and last is not None and not self._feedback_lost:
                    self._follow_odometry(now - last)
                self._speed_seen_wall = now

    def _note_report_arrival(self, frame_id: int) -> None:
        if self.clock is ClockMode.LOCKSTEP:
            self._window[frame_id] += 1
            return
        if not self._engaged:
            return
        guard = self._report_rate[frame_id]
        if not guard.arrive(frame_id, self._wall_clock()):
            self._raise("foreign_sender", f"report ID 0x{frame_id:03X} arrives faster than one frame per "
                        f"{guard.cycle_s * 1e3:.0f} ms cycle")

    def _wait_until(self, t_us: int) -> None:
        self._t_us = t_us
        delay = self._t0 + t_us / 1e6 - self._wall_clock()
        if delay > 0:
            time.sleep(delay)
