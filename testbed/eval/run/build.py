"""Builds a simulated run from a scenario: the track and vehicle, the physics world and chassis, the sensors,
the lane detector and tracker, the defense, the attack and the control loop (`RunParts`), with the checks only
the built track and vehicle can make. `SimRun` steps what this builds.

The run's random streams are spawned from the scenario seed in a fixed order (camera noise, localization,
attack, detector, then traffic), so the same scenario and seed give byte-identical trajectories.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from testbed.assembly import LanePorts, LoopRun, LoopSettings, assemble
from testbed.attacks.base import Attack, WhiteBox
from testbed.attacks.compose import AttackChain
from testbed.attacks.spec import build_attack
from testbed.camera import FrontCamera
from testbed.chassis import ChassisPort, ChassisState
from testbed.conditions import Condition, get_condition
from testbed.control.car_following import CarFollowing
from testbed.control.idm import IdmParams
from testbed.defense.base import Defense
from testbed.defense.bicycle import BicycleCoefficients
from testbed.defense.config import DefenseConfig
from testbed.defense.registry import DEFENSES, defense_settings, resolved_table
from testbed.direct_chassis import DirectChassis
from testbed.eval.run.recording import Recording
from testbed.eval.run.scenario import END_MARGIN_M, Scenario, ScenarioError, check_needs
from testbed.eval.run.video import VideoWriter
from testbed.lane_detection import CameraFrame, LaneDetection, LaneDetector
from testbed.lane_tracker import LaneTracker, TrackerParams
from testbed.localization.registry import LOCALIZATIONS
from testbed.localization.stack import LocalizationConfig
from testbed.loop import SensorPorts
from testbed.params import Params
from testbed.perception.detectors.registry import DETECTORS, make_detector
from testbed.presets import build_track, vehicle
from testbed.registry import Capability
from testbed.traffic.fleet import Fleet, PlacementError
from testbed.traffic.lead import LeadSensor
from testbed.world import PhysicsWorld, TileStreamer
from tracks.pose import Pose
from tracks.road import Track
from tracks.semantic_map import TrackMap
from vehicles.camera_rig import CameraRig
from vehicles.params import VehicleParams

FrameSink = Callable[[CameraFrame, LaneDetection], None]


@dataclass(frozen=True)
class RunOptions:
    """How a scenario is run beyond what it names. `chassis` replaces the direct PyBullet port (the CAN bridge
    does this); `world`, given with it, is the physics world behind that chassis, used for contacts. `video`
    and `record` also write camera.mp4 and run.mcap. `ground` is how the camera draws the road surface
    (`TileStreamer`). `defense`, `detector` and `attack` replace the ones the scenario names (a list of attacks
    is composed in order). `tracking` puts a `LaneTracker` after the detector (default: the scenario's
    `detector.tracking`, or for an injected detector, whether it reads the camera). `sensor_ports` wraps the
    sensor ports the run builds (sensor-level HIL passes them through real readers)."""

    render: bool | None = None
    video: bool = False
    record: bool = False
    chassis: ChassisPort | None = None
    world: PhysicsWorld | None = None
    ground: str = "canvas"
    defense: Defense | None = None
    detector: LaneDetector | None = None
    attack: Attack | list[Attack] | None = None
    tracking: bool | None = None
    sensor_ports: Callable[[SensorPorts], SensorPorts] | None = None


@dataclass
class RunParts:
    """What one simulated run is made of."""

    sc: Scenario
    track: Track
    """The road with the condition's and the attack's painters (the map reads the same geometry)."""
    params: VehicleParams
    condition: Condition
    defense_config: DefenseConfig
    """The loop's view of the `[defense]` table (`testbed.defense.registry.defense_settings`)."""
    defense_table: dict[str, Any]
    """The `[defense]` table as summary.json records it (`testbed.defense.registry.resolved_table`)."""
    smap: TrackMap
    lane: int
    start: Pose
    world: PhysicsWorld | None
    chassis: ChassisPort
    attack: Attack | None
    rig: CameraRig
    streamer: TileStreamer | None
    camera: FrontCamera | None
    video: VideoWriter | None
    recording: Recording | None
    localization: object
    detector: LaneDetector | None
    detector_name: str
    detector_settings: Params | None
    """The scenario's detector's `[detector]` parameters, defaults filled in (None for an injected detector)."""
    tracker: LaneTracker | None
    defense: Defense
    run: LoopRun
    """The assembled loop, stepped to its end (`run.loop` is the ControlLoop)."""
    lane_width: float
    traffic: Fleet | None = None
    """The traffic cars (their bodies are in `world`), or None on an empty road."""


def physics_world_for(sc: Scenario, track: Track, params: VehicleParams, start: Pose) -> PhysicsWorld:
    """The physics world a scenario runs in (the CAN chassis emulator builds the same one as its plant)."""
    return PhysicsWorld(track, params, start, physics_hz=sc.rates.physics_hz)


def _lidar_quality(track: Track) -> Callable[[float, float], float]:
    """LiDAR feature richness at a world point (the track's profile along the road)."""
    def quality(x: float, y: float) -> float:
        s, _ = track.reference.project(x, y)
        return track.lidar_feature_quality(s)
    return quality


def _localization_config(sc: Scenario, params: VehicleParams) -> Callable[[], LocalizationConfig]:
    """The scenario's localization table, with the MSF lever arm (rear axle to reference point) of the car."""
    def config() -> LocalizationConfig:
        table = dict(sc.rates.localization)
        table["msf"] = {"lever": -params.rear_axle_x, **table.get("msf", {})}
        return LocalizationConfig.from_dict(table)
    return config


def _lane_and_start(sc: Scenario, track: Track) -> tuple[int, Pose]:
    lane = sc.lane if sc.lane is not None else track.ego_lane
    if not 0 <= lane < len(track.lanes):
        raise ScenarioError(f"lane {lane} does not exist on {sc.track} ({len(track.lanes)} lanes)")
    if track.lanes[lane].oncoming:
        raise ScenarioError(f"lane {lane} of {sc.track} is an oncoming lane; the ego car drives along the road: "
                            f"lane = 0..{len(track.lanes) - track.oncoming - 1}")
    if sc.start_s > track.length - END_MARGIN_M:
        raise ScenarioError(f"start_s = {sc.start_s:g} m lies beyond the end of {sc.track} "
                            f"({track.length:.0f} m long, runs end {END_MARGIN_M:g} m before it)")
    return lane, track.start_pose(lane, sc.start_s)


def build_run(sc: Scenario, options: RunOptions, keep_frame: FrameSink) -> RunParts:
    """The parts of a run of `sc`; `keep_frame` receives each camera frame and its detection when the run
    writes a video or a recording. ScenarioError for what only the built track and vehicle can refuse."""
    o = options
    track = build_track(sc.track)
    params = vehicle(sc.vehicle)
    condition = get_condition(sc.condition)
    defense_config, defense_params = defense_settings(sc.defense, sc.defense_params)
    provided = check_needs(sc)
    if sc.speed > params.max_speed:
        raise ScenarioError(f"speed {sc.speed} m/s is beyond what {sc.vehicle} can reach ({params.max_speed} m/s)")
    root_seed = np.random.SeedSequence(sc.seed)
    seeds = root_seed.spawn(4)
    rng_camera, rng_loc, rng_attack, rng_detector = (np.random.default_rng(s) for s in seeds)
    smap = TrackMap(track)
    lane, start = _lane_and_start(sc, track)
    world, chassis = o.world, o.chassis
    if chassis is None:
        world = physics_world_for(sc, track, params, start)
        chassis = DirectChassis(world, hold_s=sc.rates.command_hold_s, model=sc.chassis,
                                steer_sensor=sc.chassis.yaw_rate == "steering")  # the loop reads it for nothing else
    rates = sc.rates
    attack = AttackChain(o.attack) if isinstance(o.attack, list) else o.attack
    if o.attack is None:
        attack = build_attack(sc.attack, rng=rng_attack, defense=defense_config)
    lidar_quality = _lidar_quality(track)
    track = track.with_painters([*condition.track_painters(sc.seed), *(attack.painters() if attack else [])])
    reads_camera = Capability.CAMERA_IMAGE in provided if o.detector is None else o.detector.reads_camera
    rig = CameraRig(params.camera)
    streamer, camera = None, None
    if (reads_camera if o.render is None else o.render) or o.video or o.record:
        streamer = TileStreamer(track, condition.lighting, ground=o.ground)
        camera = FrontCamera(streamer, rig, condition, rng_camera)
    localization = LOCALIZATIONS.get(sc.localization).factory(_localization_config(sc, params), rng_loc,
                                                               lidar_quality, start)
    detector_params = sc.run_detector_params
    detector = o.detector if o.detector is not None else make_detector(
        sc.detector, track=track, rig=rig, rng=rng_detector, params=detector_params)
    settings = DETECTORS.get(sc.detector).settings(detector_params, f"detector {sc.detector}")
    tracking = o.tracking
    if tracking is None:
        tracking = getattr(settings, "tracking", False) if o.detector is None else o.detector.reads_camera
    if tracking and detector is None:
        raise ScenarioError("tracking needs a lane detector; name one, or turn tracking off")
    if "track_at" in settings.model_fields_set and not tracking:
        raise ScenarioError("detector.track_at sets where the lane tracker measures the lines; it needs "
                            "detector.tracking = true")
    tracker = None
    if tracking:  # the scenario's `[detector] track_at`, also beside a detector given as an object; else the default
        measure_at = getattr(settings, "track_at", None)
        tracker = LaneTracker(TrackerParams() if measure_at is None else TrackerParams(measure_at=tuple(measure_at)))
    if defense_config.p_source == "reported" and detector is not None and not detector.reports_variance:
        raise ScenarioError(f"defense.p_source = 'reported' needs a lane detector that reports its c0 variance; "
                            f"{sc.detector!r} does not: use detector oracle, or defense.p_source = 'constant'")
    defense = o.defense if o.defense is not None else DEFENSES.get(sc.defense).factory(
        defense_params, BicycleCoefficients(wheelbase=params.wheelbase, lever=-params.rear_axle_x))
    capture = None
    if camera is not None:
        def capture(t: float, pose: Pose):
            streamer.update(pose)
            return camera.capture(t, pose)
    sensors = SensorPorts(localization, capture)
    traffic = _traffic(sc, track, params, lane, world, streamer, np.random.default_rng(root_seed.spawn(1)[0]))
    run = assemble(LoopSettings(sc.speed, sc.duration, sc.rates, sc.control, defense_config), chassis,
                   o.sensor_ports(sensors) if o.sensor_ports is not None else sensors, defense,
                   LanePorts(smap, lane, params,
                             planned_stop=(sc.stop_at, sc.stop_decel) if sc.stop_at is not None else None,
                             follow=_car_following(sc, traffic, smap, lane, params)),
                   detector=detector, tracker=tracker, on_frame=keep_frame if (o.video or o.record) else None,
                   attack=attack)
    if attack is not None:
        attack.know(WhiteBox(smap, lane, defense_config, rates.camera_hz, rates.control_hz, lidar_quality,
                             controller=run.loop.driving.lateral))
    detector_name = sc.detector if o.detector is None else getattr(o.detector, "name", type(o.detector).__name__)
    return RunParts(sc, track, params, condition, defense_config, resolved_table(defense_config, defense_params),
                    smap, lane, start, world, chassis, attack, rig,
                    streamer, camera, VideoWriter(rig, fps=rates.camera_hz) if o.video else None,
                    Recording(rig) if o.record else None, localization, detector, detector_name, settings, tracker,
                    defense, run, smap.lane_width(start, lane), traffic)


def _car_following(sc: Scenario, fleet: Fleet | None, smap: TrackMap, lane: int, params: VehicleParams
                   ) -> Callable[[ChassisState], float | None] | None:
    """The ego's acceleration cap behind the car ahead in its lane where `[traffic] ego_follows` asks for it."""
    if fleet is None or not sc.traffic.ego_follows:
        return None
    sensor = LeadSensor(fleet, smap, lane)
    following = CarFollowing(IdmParams(brake_limit=params.max_decel))
    return lambda state: following.cap(state.speed, sensor(state))


def _traffic(sc: Scenario, track: Track, params: VehicleParams, lane: int, world: PhysicsWorld | None,
             streamer: TileStreamer | None, rng: np.random.Generator) -> Fleet | None:
    """The scenario's traffic cars placed on the track, their bodies added to the world and, for the camera,
    to the streamer's render client (None: no traffic)."""
    if sc.traffic.vehicles == 0:
        return None
    if world is None:
        raise ScenarioError("[traffic] needs the physics world of the run; this chassis brings none")
    size = vehicle(sc.traffic.vehicle)
    try:
        fleet = Fleet.place(sc.traffic, track, lane, sc.start_s, sc.speed, rng, (size.length, size.width),
                            (params.length, params.width), track.length - END_MARGIN_M)
    except PlacementError as exc:
        raise ScenarioError(str(exc)) from None
    poses = dict(enumerate(fleet.poses()))
    world.add_traffic(len(fleet.cars), size.length, size.width, size.height)
    world.place_traffic(poses)
    if streamer is not None:
        streamer.add_traffic(len(fleet.cars), size.length, size.width, size.height)
        streamer.place_traffic(poses)
    return fleet
