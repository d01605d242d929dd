"""A scenario driven over the CAN link: the loop, outputs and summary of `ld3 run`, with the CAN bridge as the
chassis port and every frame the bridge sends or receives logged next to the outputs (can.Logger).

Where the vehicle sits, by interface: `virtual` -> an ECU emulator in this process (lockstep) on its own
virtual channel, its plant the PyBullet world the run also checks for curb and barrier contacts; `slcan`
without a channel -> the ECU emulator as a separate process speaking SLCAN on a pty (lockstep); any other
interface, or `slcan` with a channel -> an external VCU (realtime by default unless the bus is a pty).
The consequence and the deviation figures are judged on one pose, which the summary's `consequence_basis` names
(`hil.emulator.consequence_basis`): the emulated plant's where the run's emulator gives it, else the odometry's;
odometry's own figures stay beside them (`odometry_max_abs_dev_m`, `odometry_final_dev_m`).
The chassis profile (`LinkConfig.profile`) sets the protocol of bridge and emulator (a secured profile's key:
`hil.link.secoc_key.link_key`, resolved before any bus opens); the bridge's pose is its odometry from the scenario's
start pose and the vehicle's geometry. A run that latches a fault brakes to standstill in lane and ends as
chassis_fault (summary `faults`); the outputs and the CAN log are still written. A lost link (link_lost) and
an operator's SIGINT or SIGTERM (interrupted) are such faults too.
"""

from __future__ import annotations

import contextlib
import dataclasses
import uuid
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import can
import numpy as np

from hil.emulator.consequence_basis import ConsequenceBasis, consequence_basis
from hil.emulator.ecu import EcuEmulator, EcuLimits
from hil.emulator.plants import plant_args_for, scenario_plant
from hil.emulator.sensor_io import SENSOR_MODES, SensorIo
from hil.link.bridge import BridgeError, CanChassisBridge
from hil.link.bus_config import BusConfig
from hil.link.ecu_process import EcuProcess
from hil.link.errors import LINK_ERRORS
from hil.link.faults import one_line
from hil.link.interruption import interruptible
from hil.link.mcap_can import CanToRecording
from hil.link.odometry import KinematicOdometry, OdometryGeometry
from hil.link.profile import DEFAULT_PROFILE, ChassisProfile, load_profile
from hil.link.recorder import LOG_SUFFIXES, RUN_LOG, FrameRecorder
from hil.link.secoc_key import link_key
from hil.link.timing import ClockMode
from hil.link.wheels import WheelGeometry
from hil.link.yaw_rate import YawRateChassis, yaw_rate_source
from testbed.errors import UserError
from testbed.eval.run.folder import claimed_out_dir
from testbed.eval.run.runner import RunResult, SimRun, max_abs_dev
from testbed.eval.run.scenario import Scenario
from testbed.eval.run.summary import HilSummary
from testbed.loop import TickRecord
from testbed.presets import build_track, vehicle
from testbed.world import PhysicsWorld

ECU_PLANT = "hil.emulator.plants:pybullet_plant"


@dataclass(frozen=True)
class LinkConfig:
    """Which bus carries the run (any python-can interface, its channel, bitrate, options and configuration
    section: `hil.link.bus_config`), how time advances on it (None: lockstep on an emulator's bus, realtime on
    hardware), the chassis profile (shipped name or folder) and whether an emulator publishes truth frames
    (None: the profile's)."""

    interface: str = "virtual"
    channel: str | None = None
    clock: ClockMode | None = None
    profile: str = DEFAULT_PROFILE
    truth: bool | None = None
    bitrate: int | None = None
    options: Mapping[str, Any] = field(default_factory=dict)
    context: str | None = None

    def __post_init__(self) -> None:
        if not self.spawns_ecu:
            self.bus(self.channel).kwargs()  # an unknown interface or a missing channel is refused here

    @property
    def spawns_ecu(self) -> bool:
        """SLCAN without a channel: the ECU emulator runs in its own process on a pty."""
        return self.interface == "slcan" and not self.channel

    def bus(self, channel: str | None) -> BusConfig:
        return BusConfig(self.interface, channel, self.bitrate, self.options, self.context)

    @property
    def clock_mode(self) -> ClockMode:
        if self.clock is not None:
            return self.clock
        hardware = not self.spawns_ecu and self.bus(self.channel).hardware
        return ClockMode.REALTIME if hardware else ClockMode.LOCKSTEP


def scenario_odometry(sc: Scenario) -> KinematicOdometry:
    """Odometry from the scenario's start pose with its vehicle's wheelbase and reference point."""
    track = build_track(sc.track)
    params = vehicle(sc.vehicle)
    lane = sc.lane if sc.lane is not None else track.ego_lane
    geometry = OdometryGeometry(wheelbase=params.wheelbase, ref_ahead=-params.rear_axle_x)
    return KinematicOdometry(track.start_pose(lane, sc.start_s), geometry)


class HilLink:
    """An engaged CanChassisBridge and the emulated vehicle behind it (if any); `close()` tears both down."""

    def __init__(self, sc: Scenario, config: LinkConfig, reply_timeout: float = 5.0) -> None:
        self.config = config
        self.profile: ChassisProfile = load_profile(config.profile)
        self.world: PhysicsWorld | None = None
        self.channel = config.channel
        self._ecu: EcuEmulator | None = None
        self._ecu_bus: can.BusABC | None = None
        self._process: EcuProcess | None = None
        self.sensor_io: SensorIo | None = None
        """The sensor readers of a `--sensors io` run (None: the simulated sensors feed the loop directly)."""
        clock = config.clock_mode
        spawns_ecu = config.spawns_ecu
        self.key = link_key(self.profile, "slcan-pty" if spawns_ecu else config.interface, config.channel)
        if config.interface == "virtual":
            self.channel = config.channel or f"ld3-hil-{uuid.uuid4().hex[:12]}"
            plant = scenario_plant(sc)
            self.world = plant.world
            self._ecu_bus = BusConfig("virtual", self.channel).open()
            self._ecu = EcuEmulator(self._ecu_bus, plant, EcuLimits(), clock, profile=self.profile,
                                    truth=config.truth, key=self.key, wheels=WheelGeometry.of(vehicle(sc.vehicle)))
            self._ecu.start()
        elif spawns_ecu:
            self._process = EcuProcess(plant=ECU_PLANT, plant_args=plant_args_for(sc), clock=clock,
                                       profile=str(self.profile.root), truth=config.truth)
            self.channel = self._process.tty_path
        try:
            self.bus = config.bus(self.channel).open()
        except Exception:
            self._stop_vehicle()
            raise
        self.bridge = CanChassisBridge(self.bus, clock=clock, reply_timeout=reply_timeout, profile=self.profile,
                                       odometry=scenario_odometry(sc), key=self.key)

    @property
    def ecu(self) -> EcuEmulator | None:
        """The in-process ECU emulator (virtual interface), else None."""
        return self._ecu

    @property
    def consequence_basis(self) -> ConsequenceBasis:
        """The pose the run is judged on: the in-process plant's, the truth frames of the ECU process this link
        started where it publishes them, else the odometry's."""
        truth_on = self.config.truth if self.config.truth is not None else self.profile.simulation.truth
        truth = self.bridge.follower.truth_pose if self._process is not None and truth_on else None
        return consequence_basis(self._ecu.plant if self._ecu is not None else None, truth)

    def engage(self, timeout: float = 5.0) -> None:
        self.bridge.engage(timeout=timeout)

    def close(self) -> None:
        """Brake to standstill and hand control back (best effort), stop the bridge, the ECU and the buses."""
        with contextlib.suppress(BridgeError, can.CanError, OSError):  # must not mask the run's own outcome
            self.bridge.stop_and_release(timeout=10.0)
        self.bridge.close()
        with contextlib.suppress(can.CanError, OSError):  # a dead device cannot be closed cleanly
            self.bus.shutdown()
        self._stop_vehicle()

    def _stop_vehicle(self) -> None:
        if self._ecu is not None:
            self._ecu.stop()
        if self._ecu_bus is not None:
            self._ecu_bus.shutdown()
        if self._process is not None:
            self._process.stop()


def _drive(sim: SimRun, bridge: CanChassisBridge, progress: bool) -> RunResult:
    """Run the loop to its end; a link error in the loop's own thread latches link_lost and a second
    interruption cuts the in-lane stop short, both ending the run with the ticks so far."""
    try:
        return sim.run(progress=progress)
    except LINK_ERRORS as exc:
        bridge.link_lost(one_line(exc))
    except KeyboardInterrupt:
        pass
    return sim.result()


def _odometry_figures(rows: list[TickRecord]) -> dict[str, float | None]:
    """max |D| and final D of the bridge's odometry pose (the pose the loop's chassis port reports)."""
    devs = np.array([np.nan if r.phys_dev is None else r.phys_dev for r in rows])
    return {"odometry_max_abs_dev_m": max_abs_dev(devs),
            "odometry_final_dev_m": float(devs[-1]) if len(devs) else None}


def _log_name(log_path: Path | None, out_dir: Path | None) -> str | None:
    """The CAN log as the summary names it: relative to the run folder when it lies inside it (the folder may be
    written under a temporary name and renamed into place), else the path given."""
    if log_path is None:
        return None
    if out_dir is not None and log_path.is_relative_to(out_dir):
        return log_path.relative_to(out_dir).as_posix()
    return str(log_path)


def run_hil_scenario(sc: Scenario, out_dir: Path | None, config: LinkConfig = LinkConfig(), *,
                     log_path: Path | None = None, progress: bool = False,
                     prepare: Callable[[HilLink], None] | None = None, reply_timeout: float = 5.0,
                     record: bool = False, sensors: str = "sim", force: bool = False) -> RunResult:
    """Run `sc` over the CAN link; with `out_dir` write the `ld3 run` outputs plus the CAN log
    (`log_path`, default OUT/can.asc), and with `record` run.mcap with the CAN frames decoded by the profile's
    DBC. The summary is judged on `HilLink.consequence_basis` and gains it, interface, channel, clock, profile,
    frame counts, odometry's own deviation figures and its largest and final distance from the emulator's truth
    (where truth frames are on). `prepare` is called with the link before engaging (fault drills install their
    injections there). `sensors` "io" routes GNSS and camera through the real readers (`hil.emulator.sensor_io`; the
    link's `sensor_io` then). A finished run in `out_dir` is replaced only with `force`, and only once this run is
    written (`claimed_out_dir`)."""
    if sensors not in SENSOR_MODES:
        raise UserError(f"sensors must be one of {', '.join(SENSOR_MODES)}, got {sensors!r}")
    if sc.chassis.yaw_rate != "sensed":
        raise UserError(f"[chassis] yaw_rate = {sc.chassis.yaw_rate!r} is the simulated chassis's; over CAN the "
                        f"profile says where the yaw rate comes from (the summary's yaw_rate_source)")
    if sc.chassis.steer_offset_deg and not (config.interface == "virtual" or config.spawns_ecu):
        raise UserError(f"[chassis] steer_offset_deg miscalibrates the emulated chassis; the chassis on "
                        f"{config.interface} has its own")
    if log_path is not None and log_path.suffix not in LOG_SUFFIXES:
        raise UserError(f"CAN log must end in {' or '.join(LOG_SUFFIXES)}: {log_path}")
    link = HilLink(sc, config, reply_timeout=reply_timeout)  # first: a refused link leaves no folder or log behind
    basis = link.consequence_basis
    if out_dir is not None:
        log_path = log_path or out_dir / RUN_LOG
    with contextlib.ExitStack() as claim:
        recorder: FrameRecorder | None = None
        sim: SimRun | None = None
        try:
            if out_dir is not None:  # an earlier run there comes back unless this one finishes and is written
                claim.enter_context(claimed_out_dir(out_dir, force))
            if log_path is not None:
                recorder = FrameRecorder(log_path)
                link.bridge.add_listener(recorder)
            if sensors == "io":
                link.sensor_io = SensorIo(link.bridge.time, link.bridge.sensor_fault)
            if prepare is not None:
                prepare(link)
            chassis = YawRateChassis(link.bridge, link.profile, vehicle(sc.vehicle))
            sim = SimRun(sc, chassis=chassis, world=link.world, record=record,
                         sensor_ports=link.sensor_io.wrap if link.sensor_io is not None else None,
                         plant_pose=basis.pose)
            if sim.parts.recording is not None:
                link.bridge.add_listener(CanToRecording(sim.parts.recording, link.profile.db, link.bridge.time))
            with interruptible(link.bridge.interrupt):
                link.engage()  # last before the run: a realtime bridge starts its clock here
                result = _drive(sim, link.bridge, progress)
        finally:
            link.close()
            if link.sensor_io is not None:
                link.sensor_io.close()
            if recorder is not None:
                recorder.stop()
            if sim is not None:
                sim.close()
            elif link.world is not None:
                link.world.close()
        bridge = link.bridge
        result = dataclasses.replace(result, record=HilSummary(**result.summary, **{
            "interface": config.interface, "channel": link.channel, "clock": config.clock_mode.value,
            "profile": link.profile.name, "pose_source": "odometry", "consequence_basis": basis.name,
            **_odometry_figures(result.rows),
            "yaw_rate_source": yaw_rate_source(link.profile), "odometry_error_max_m": bridge.odometry_error_max_m,
            "odometry_error_final_m": bridge.odometry_error_last_m,
            "can_log": _log_name(log_path, out_dir),
            "can_frames_tx": bridge.frames_tx, "can_frames_rx": bridge.frames_rx,
            "can_frames_rejected": sum(bridge.rejected.values()),
            "can_frames_logged": recorder.frames if recorder is not None else 0,
            "sensors": sensors, **(link.sensor_io.counts() if link.sensor_io is not None else {}),
        }))
        if out_dir is not None:
            sim.write_outputs(out_dir, result, title_suffix=f" · CAN {config.interface}")
    return result
