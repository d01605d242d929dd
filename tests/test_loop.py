"""The loop's tick order (docs/architecture.md, "One control tick"), pinned against a kinematic plant on a real
track map.

Every port is wrapped so that each call appends its name to one shared log; the test reads the log back
tick by tick.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from hil.emulator.kinematic_plant import KinematicBicyclePlant
from testbed.attacks.base import Attack
from testbed.control.lateral import LqrLateralController
from testbed.control.longitudinal import SpeedController
from testbed.control.planner import LanePlanner
from testbed.defense.config import DefenseConfig
from testbed.defense.ld3 import Ld3Defense
from testbed.lane_detection import CameraFrame
from testbed.localization.sensors import GnssFix
from testbed.localization.stack import GroundTruthLocalization
from testbed.loop import ControlLoop, DrivingPorts, PerceptionPorts, SensorPorts
from testbed.perception.detectors.oracle import OracleLaneDetector
from testbed.rates import Rates
from tracks.presets import load_track
from tracks.semantic_map import TrackMap
from vehicles.params import get_vehicle


class Traced:
    """Forwards every attribute of `inner`; calls of the `methods` named are logged as `label.method`."""

    def __init__(self, inner: Any, label: str, log: list[str], methods: tuple[str, ...]) -> None:
        self._inner, self._label, self._log, self._methods = inner, label, log, methods

    def __getattr__(self, name: str) -> Any:
        attr = getattr(self._inner, name)
        if name not in self._methods:
            return attr

        def traced(*args: Any, **kwargs: Any) -> Any:
            self._log.append(f"{self._label}.{name}")
            return attr(*args, **kwargs)

        return traced


class GnssEveryTick(GroundTruthLocalization):
    """The true pose, plus a GNSS fix at the true position on every step, passed through the spoofer."""

    def step(self, t, truth, spoof_gnss=None):
        fix = GnssFix(t, np.array([truth.true_pose.x, truth.true_pose.y]), np.eye(2))
        self.last_gnss = spoof_gnss(fix) if spoof_gnss is not None else fix
        return super().step(t, truth, spoof_gnss)


class PassiveAttack(Attack):
    """Changes nothing; logs which hooks the loop calls."""

    def __init__(self, log: list[str]) -> None:
        super().__init__(start_time=0.0)
        self.log = log

    def spoof_gnss(self, fix, view):
        self.log.append("attack.spoof_gnss")
        return fix

    def tamper_msf(self, est, view):
        self.log.append("attack.tamper_msf")
        return est

    def tamper_ld(self, ld, view):
        self.log.append("attack.tamper_ld")
        return ld

    def state(self) -> dict[str, Any]:
        return {"stage": "passive"}

    def describe(self) -> dict[str, Any]:
        return {"kind": "passive"}


@pytest.fixture()
def traced_loop(request):
    log: list[str] = []
    track = load_track("urban-straight@1")
    smap = TrackMap(track)
    params = get_vehicle("sedan")
    start = track.start_pose(s=20.0)
    plant = KinematicBicyclePlant(wheelbase=params.wheelbase, pose=start, speed=10.0)
    chassis = Traced(plant, "chassis", log, ("read", "send", "advance"))
    source = GnssEveryTick() if getattr(request, "param", "") == "gnss" else GroundTruthLocalization()
    localization = Traced(source, "localization", log, ("step",))

    def camera(t: float, pose) -> CameraFrame:
        log.append("camera")
        return CameraFrame(t, None, pose)

    detector = Traced(OracleLaneDetector(track, np.random.default_rng(0)), "detector", log, ("detect",))
    defense = Traced(Ld3Defense(DefenseConfig()), "defense", log,
                     ("on_odometry", "on_gnss", "on_lane_detection", "pose_for_control", "on_command"))
    frames: list[float] = []
    lane = track.ego_lane
    driving = DrivingPorts(
        smap, lane,
        Traced(LanePlanner(smap, lane, 10.0), "planner", log, ("plan", "start_stop")),
        Traced(LqrLateralController.from_vehicle(params, 0.01), "lateral", log, ("update",)),
        Traced(SpeedController(max_accel=params.max_accel, max_decel=params.max_decel), "longitudinal", log,
               ("update",)),
        planned_stop=(0.25, 3.0),
    )
    loop = ControlLoop(chassis, SensorPorts(localization, camera),
                       PerceptionPorts(detector, 0.5, lambda frame, ld: frames.append(frame.t)),
                       defense, driving, attack=PassiveAttack(log),
                       rates=Rates(physics_hz=100.0, control_hz=100.0, camera_hz=20.0))
    return loop, log, frames, plant


def _ticks(loop: ControlLoop, log: list[str], n: int) -> list[list[str]]:
    out = []
    for _ in range(n):
        log.clear()
        loop.tick()
        out.append(list(log))
    return out


CAMERA_TICK = [
    "chassis.read", "defense.on_odometry", "localization.step", "attack.tamper_msf",
    "camera", "detector.detect", "attack.tamper_ld", "defense.on_lane_detection",
    "defense.pose_for_control", "planner.plan", "lateral.update", "longitudinal.update",
    "chassis.send", "defense.on_command", "chassis.advance",
]
PLAIN_TICK = [c for c in CAMERA_TICK if c not in ("camera", "detector.detect", "attack.tamper_ld",
                                                    "defense.on_lane_detection")]


def test_tick_order_with_and_without_a_camera_frame(traced_loop):
    loop, log, frames, _ = traced_loop
    ticks = _ticks(loop, log, 10)
    assert ticks[0] == CAMERA_TICK
    assert ticks[1:5] == [PLAIN_TICK] * 4
    assert ticks[5] == CAMERA_TICK
    assert frames == pytest.approx([0.0, 0.05])


def test_planned_stop_starts_once_before_planning(traced_loop):
    loop, log, _, plant = traced_loop
    ticks = _ticks(loop, log, 40)
    starts = [i for i, calls in enumerate(ticks) if "planner.start_stop" in calls]
    assert starts == [25]
    calls = ticks[25]
    assert calls.index("defense.pose_for_control") < calls.index("planner.start_stop") < calls.index("planner.plan")
    assert loop.stopping
    assert plant.read().speed < 10.0


def test_the_defense_gets_the_chassis_odometry_every_tick(traced_loop):
    loop, _, _, plant = traced_loop
    seen: list[tuple[float, float, float]] = []
    loop.defense.on_odometry = lambda t, speed, yaw_rate: seen.append((t, speed, yaw_rate))
    expected = []
    for _ in range(30):
        state = plant.read()
        expected.append((state.t, state.speed, state.yaw_rate))
        loop.tick()
    assert seen == expected and seen[-1][1] < seen[0][1]  # speeds read as the planned stop brakes


def test_records_one_row_per_tick_with_the_plants_time_and_a_fresh_flag(traced_loop):
    loop, _, _, plant = traced_loop
    rows = [loop.tick() for _ in range(12)]
    assert [r.t for r in rows] == pytest.approx([i * 0.01 for i in range(12)])
    assert [r.ld_fresh for r in rows] == [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0]
    assert all(r.mode == "normal" for r in rows)
    assert rows[-1].phys_dev == pytest.approx(0.0, abs=0.05)
    assert plant.read().t == pytest.approx(0.12)


@pytest.mark.parametrize("traced_loop", ["gnss"], indirect=True)
def test_a_gnss_fix_is_spoofed_inside_the_localization_step_and_reaches_the_defense_before_the_camera(traced_loop):
    loop, log, _, _ = traced_loop
    calls = _ticks(loop, log, 1)[0]
    assert calls[:7] == ["chassis.read", "defense.on_odometry", "localization.step", "attack.spoof_gnss",
                         "attack.tamper_msf", "defense.on_gnss", "camera"]


def test_the_tracker_and_the_lateral_controller_read_the_defense_s_corrected_yaw_rate(traced_loop):
    """A defense that estimates the chassis yaw rate's bias hands the loop the corrected rate: the lane tracker
    predicts with it and the lateral controller damps with it; the defense itself gets the rate as reported."""
    loop, _, _, plant = traced_loop
    tracked, damped = [], []
    loop.defense.odometry_yaw_rate = lambda speed, yaw_rate: yaw_rate + 0.25
    assert loop.perception.tracker is None  # the fixture runs none: a spy takes its place
    object.__setattr__(loop.perception, "tracker", Traced(_Spy(tracked), "tracker", [], ("update",)))
    lateral = loop.driving.lateral
    update = lateral.update
    lateral.update = lambda plan, speed, yaw_rate: damped.append(yaw_rate) or update(plan, speed, yaw_rate=yaw_rate)
    expected = []
    for _ in range(6):
        expected.append(plant.read().yaw_rate + 0.25)
        loop.tick()
    assert damped == pytest.approx(expected) and tracked == pytest.approx([expected[0], expected[5]])


class _Spy:
    """A lane tracker that passes the detection through and keeps the yaw rate it was given."""

    def __init__(self, seen: list[float]) -> None:
        self.seen = seen

    def update(self, ld, speed, yaw_rate):
        self.seen.append(yaw_rate)
        return ld
