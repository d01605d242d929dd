"""CAN chassis bridge: a ChassisPort whose vehicle (ECU emulator or real chassis) sits behind a CAN bus.

Commands go out as the three command frames under the 50 Hz rule of `hil.timing`; reports are followed
through a can.Notifier and verified by the codec (rejections are counted, never applied). `engage`
performs the enable handshake: release cycles until the VCU reports standby without a latched fault, then
enable cycles until it reports self-driving. Any frame received on a command ID came from another
transmitter (a bus does not echo our own frames), so it raises the bridge's own foreign_node fault.
ChassisState.mode and .faults carry the VCU's driving mode and faults.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

import can

from hil.actuator_map import COMMAND_FRAMES, ActuatorRequest
from hil.codec import ChassisCodec, FrameRejected
from hil.report_map import DRIVE_STATUS, DrivingMode, ReportFollower
from hil.timing import (
    COMMAND_TIMEOUT_S,
    CYCLE_S,
    CYCLE_US,
    STEP_DONE,
    STEP_REQUEST,
    ClockMode,
    CommandSchedule,
)
from testbed.chassis import ChassisCommand, ChassisPort, ChassisState

MAX_STEP_US = CYCLE_US
COMM_FAULTS = ("command_timeout", "bad_frames", "foreign_node")


class BridgeError(RuntimeError):
    """The VCU did not answer as required (lockstep step reply or enable handshake)."""


class CanChassisBridge(ChassisPort):
    """ChassisPort over a python-can bus in lockstep (simulation) or realtime (hardware) clock mode."""

    def __init__(
        self,
        bus: can.BusABC,
        clock: ClockMode = ClockMode.LOCKSTEP,
        steer_rate: float = 1.0,
        reply_timeout: float = 2.0,
        wall_clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.bus = bus
        self.clock = clock
        self.steer_rate = steer_rate
        self.reply_timeout = reply_timeout
        self._wall_clock = wall_clock
        self.codec = ChassisCodec()
        self.follower = ReportFollower()
        self._foreign_ids = frozenset(self.codec.frame_id(n) for n in (*COMMAND_FRAMES, STEP_REQUEST))
        self._listeners: list[can.Listener] = []
        self._tx_lock = threading.Lock()
        self._cmd = ChassisCommand(0.0, 0.0)
        self._enable = False
        self._t_us = 0
        self._t0 = wall_clock()
        self._schedule = CommandSchedule()
        self._step = 0
        self._done = threading.Condition()
        self._done_echo: int | None = None
        self._last_report_wall: float | None = None
        self.rejected = {"format": 0, "checksum": 0, "range": 0, "counter": 0}
        self.frames_tx = 0
        self.frames_rx = 0
        self.frames_accepted = 0
        self.foreign_node = False
        self._stop = threading.Event()
        self._notifier = can.Notifier(bus, [self.handle], timeout=0.05)
        self._sender: threading.Thread | None = None
        if clock is ClockMode.REALTIME:
            self._sender = threading.Thread(target=self._send_loop, name="bridge-50hz", daemon=True)
            self._sender.start()

    # ------------------------------------------------------------------ ChassisPort
    def read(self) -> ChassisState:
        extra = []
        if self.foreign_node:
            extra.append("foreign_node")
        if self.clock is ClockMode.REALTIME and self._report_stale():
            extra.append("report_timeout")
        state = self.follower.state(self.time(), ())
        faults = tuple(dict.fromkeys((*state.faults, *extra)))
        return ChassisState(
            t=state.t,
            speed=state.speed,
            steer=state.steer,
            accel=state.accel,
            true_pose=state.true_pose,
            yaw_rate=state.yaw_rate,
            mode=state.mode,
            faults=faults,
        )

    def send(self, cmd: ChassisCommand) -> None:
        self._cmd = cmd

    def advance(self, dt: float) -> None:
        if self.clock is ClockMode.REALTIME:
            self._wait_until(self._t_us + round(dt * 1e6))
            return
        end_us = self._t_us + round(dt * 1e6)
        while self._t_us < end_us:
            to_boundary = CYCLE_US - self._t_us % CYCLE_US
            step_us = min(end_us - self._t_us, to_boundary, MAX_STEP_US)
            self._exchange(step_us, send_commands=self._schedule.due(self._t_us))
            self._t_us += step_us

    # ------------------------------------------------------------------ public extras
    def time(self) -> float:
        """Chassis time: plant time in lockstep; in realtime, wall time from the epoch the last `engage` set."""
        if self.clock is ClockMode.LOCKSTEP:
            return self._t_us / 1e6
        return self._wall_clock() - self._t0

    def add_listener(self, listener: can.Listener) -> None:
        """Give `listener` every frame this bridge sends (is_rx False) and receives."""
        self._listeners.append(listener)
        self._notifier.add_listener(listener)

    def engage(self, timeout: float = 2.0) -> None:
        """Enable handshake: release until standby without a latched fault, then enable until self-driving."""
        self._handshake(
            False, timeout, lambda: self.follower.mode is DrivingMode.STANDBY and not self._comm_faults()
        )
        self._handshake(True, timeout, lambda: self.follower.mode is DrivingMode.SELF_DRIVING)
        if self.clock is ClockMode.REALTIME:
            # the run's clock starts here: pacing from construction would replay set-up time as a burst of steps
            self._t0 = self._wall_clock() - self._t_us / 1e6

    def release(self, timeout: float = 2.0) -> None:
        """Hand control back: release cycles until the VCU reports standby."""
        self._handshake(False, timeout, lambda: self.follower.mode is DrivingMode.STANDBY)

    def close(self) -> None:
        self._stop.set()
        if self._sender is not None:
            self._sender.join(timeout=1.0)
        self._notifier.stop()

    # ------------------------------------------------------------------ internals
    def _comm_faults(self) -> bool:
        return any(f in COMM_FAULTS for f in self.follower.faults())

    def _handshake(self, enable: bool, timeout: float, reached: Callable[[], bool]) -> None:
        self._enable = enable
        deadline = self._wall_clock() + timeout
        while not reached():
            if self._wall_clock() > deadline:
                state = self.read()
                phase = "enable" if enable else "release"
                raise BridgeError(f"{phase} handshake timed out: mode {state.mode}, faults {state.faults}")
            if self.clock is ClockMode.LOCKSTEP:
                self._exchange(0, send_commands=True)
            else:
                time.sleep(CYCLE_S)

    def _exchange(self, step_us: int, send_commands: bool) -> None:
        """Lockstep: (commands,) SIM_StepRequest, then wait for the SIM_StepDone closing its reports."""
        if send_commands:
            self._send_cycle()
        self._step = (self._step + 1) % 65536
        with self._done:
            self._done_echo = None
        self._transmit(self.codec.encode(STEP_REQUEST, {"StepCount": self._step, "StepDt": step_us / 1e6}))
        with self._done:
            if not self._done.wait_for(lambda: self._done_echo == self._step, timeout=self.reply_timeout):
                raise BridgeError(f"no SIM_StepDone for step {self._step} within {self.reply_timeout} s")

    def _send_cycle(self) -> None:
        request = ActuatorRequest.from_command(self._cmd, enable=self._enable, steer_rate=self.steer_rate)
        for name, signals in request.to_signals().items():
            self._transmit(self.codec.encode(name, signals))

    def _transmit(self, frame: can.Message) -> None:
        with self._tx_lock:
            frame.timestamp = time.time()
            self.bus.send(frame)
            self.frames_tx += 1
            frame.is_rx = False
            for listener in self._listeners:
                listener.on_message_received(frame)

    def handle(self, frame: can.Message) -> None:
        """Process one received frame (the can.Notifier callback)."""
        self.frames_rx += 1
        if frame.arbitration_id in self._foreign_ids and not frame.is_extended_id:
            self.foreign_node = True
            return
        if not self.codec.knows(frame.arbitration_id):
            return
        try:
            decoded = self.codec.decode(frame)
        except FrameRejected as rejection:
            self.rejected[rejection.reason] += 1
            return
        self.frames_accepted += 1
        if decoded.name == STEP_DONE:
            with self._done:
                self._done_echo = int(decoded.signals["StepCountEcho"])
                self._done.notify_all()
            return
        self.follower.update(decoded)
        if decoded.name == DRIVE_STATUS:
            self._last_report_wall = self._wall_clock()

    def _report_stale(self) -> bool:
        last = self._last_report_wall
        return last is None or self._wall_clock() - last > COMMAND_TIMEOUT_S

    def _wait_until(self, t_us: int) -> None:
        self._t_us = t_us
        delay = self._t0 + t_us / 1e6 - self._wall_clock()
        if delay > 0:
            time.sleep(delay)

    def _send_loop(self) -> None:
        deadline = self._wall_clock()
        while not self._stop.is_set():
            self._send_cycle()
            now = self._wall_clock()
            deadline = deadline + CYCLE_S if deadline + CYCLE_S > now else now + CYCLE_S
            self._stop.wait(max(deadline - self._wall_clock(), 0.0))
