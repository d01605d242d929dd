"""The PyBullet world: a physics client (ground, roadside collision bodies, the vehicle) stepped at a
fixed rate, and the track streamed around the car for the camera: a ground canvas and the roadside boxes for
TinyRenderer's compiled clone, or a separate render client holding the boxes as bodies (where the clone is not
built) and the textured tiles (mesh mode).

Two clients, because TinyRenderer never frees a loaded texture: the render client is reset whenever
its texture budget is spent and reloads only the tiles near the car, so a road of any length runs
in bounded memory while the physics client (and the car in it) is never touched.
"""

from __future__ import annotations

import logging
import math
import tempfile
from collections.abc import Callable, Sequence
from pathlib import Path

import cv2
import numpy as np
import pybullet as pb

from testbed import physics_clients
from testbed.errors import UserError
from testbed.ground import SEGMENT_SPACING_M, GroundCanvas, Lighting
from testbed.rates import PHYSICS_HZ
from testbed.tiny_boxes import TinyBoxes, box_mesh
from testbed.tiny_boxes import kernel as tiny_kernel
from tracks.obstacles import clear_band, road_obstacles
from tracks.pose import Pose
from tracks.texture import tile_mesh, tile_texture
from vehicles.params import VehicleParams
from vehicles.pybullet_vehicle import PyBulletVehicle

log = logging.getLogger(__name__)

OBSTACLE_COLOURS: dict[str, tuple[float, float, float, float]] = {
    "curb": (0.72, 0.72, 0.70, 1.0),
    "barrier": (0.80, 0.78, 0.74, 1.0),
    "guardrail": (0.75, 0.77, 0.80, 1.0),
    "divider": (0.85, 0.85, 0.82, 1.0),
    "tree": (0.20, 0.38, 0.16, 1.0),
}
TRAFFIC_COLOURS: tuple[tuple[float, float, float, float], ...] = (
    (0.55, 0.08, 0.08, 1.0), (0.12, 0.20, 0.45, 1.0), (0.85, 0.85, 0.85, 1.0), (0.15, 0.15, 0.16, 1.0),
    (0.45, 0.47, 0.50, 1.0))
"""Body colours of the traffic cars the camera sees (car i gets colour i modulo their number)."""
HIDDEN_Z = -100.0
"""Height (m) at which a traffic body out of the car's reach waits, below the ground plane."""
MESH_SPACING_M = SEGMENT_SPACING_M
GROUND_MODES = ("canvas", "mesh")
PAINTED_KINDS = frozenset({"curb"})
OBSTACLE_UPDATE_STEPS = 24
CONTACT_SLACK_M = 0.25
"""Added to the reach within which `PhysicsWorld.contact_kinds` asks PyBullet for contacts: Bullet keeps a contact
point until its bodies part by its breaking threshold (0.02 m), and the path over a few steps is not the chord."""
CONTACT_SKIP_STEPS = 4
"""`contact_kinds` skips its query only within this many physics steps of the last one (its reach counts the car's
motion since then as the chord)."""


def obstacle_window(params: VehicleParams, physics_hz: float) -> float:
    """Along-road radius (m) around the car within which its roadside bodies are kept: twice the car's length and
    the road it covers at its top speed between two updates (`OBSTACLE_UPDATE_STEPS` physics steps), so every
    body it can touch before the next update is there (the factor covers its station running ahead of its path
    on the inside of a bend, and a speed past its governor's cap)."""
    return 2.0 * (params.max_speed * OBSTACLE_UPDATE_STEPS / physics_hz + params.length)


class PhysicsWorld:
    """Physics client: flat ground, the track's static collision bodies near the car, and one vehicle.

    Roadside bodies are streamed like the render tiles (one compound body per tile and kind, for the tiles
    within `obstacle_window_m` of the car, by default `obstacle_window`): Bullet updates an awake body's bounds
    each step, so loading a whole road's curbs at once would make each step an order of magnitude slower. The
    ground, the roadside bodies and the traffic cars' bodies are rigid bodies (maximal coordinates): as
    fixed-base multibodies, each would have its dynamics run every step; the roadside bodies are put to sleep,
    which keeps Bullet from recomputing their bounds every step (they never move), not from colliding with the car.

    `contact_kinds` answers without asking PyBullet (an empty set, what the query would return) while no roadside
    body or shown traffic car can be within reach of the car; with `verify_skips` it asks anyway and raises when
    a skipped query had contacts (tests).
    """

    def __init__(self, track, params: VehicleParams, start: Pose, physics_hz: float = PHYSICS_HZ,
                 obstacle_window_m: float | None = None) -> None:
        self.client = physics_clients.connect()
        self._released = False
        self.track = track
        self.dt = 1.0 / physics_hz
        self.t = 0.0
        self.steps = 0
        self.window = obstacle_window(params, physics_hz) if obstacle_window_m is None else obstacle_window_m
        pb.setGravity(0, 0, -9.81, physicsClientId=self.client)
        pb.setPhysicsEngineParameter(fixedTimeStep=self.dt, numSolverIterations=10, physicsClientId=self.client)
        plane = pb.createCollisionShape(pb.GEOM_PLANE, physicsClientId=self.client)
        self.ground_id = pb.createMultiBody(0, plane, useMaximalCoordinates=True, physicsClientId=self.client)
        pb.changeDynamics(self.ground_id, -1, lateralFriction=1.0, physicsClientId=self.client)
        self.obstacle_kind: dict[int, str] = {}
        self._tile_bodies: dict[int, list[int]] = {}
        self.traffic_bodies: list[int] = []
        self._traffic_z = 0.0
        self._traffic_shown: set[int] = set()
        self._traffic_poses: dict[int, Pose] = {}
        self._stepped_traffic: dict[int, Pose] = {}
        self._traffic_reach = 0.0
        self._move = _client_move(self.client)
        self.vehicle = PyBulletVehicle(self.client, params, start)
        self._band = clear_band(track)
        self._reach = _body_reach(self.client, self.vehicle, params.cg_height)
        self._contiguous = False
        self._last_query: tuple[int, Pose] | None = None
        self.verify_skips = False
        self.skipped = 0
        """Contact queries answered without PyBullet so far."""
        self.update_obstacles(start)

    def update_obstacles(self, pose: Pose) -> None:
        """Load the roadside bodies of the tiles within the window of the pose; drop the others."""
        wanted = set(self.track.tiles_near(pose.x, pose.y, self.window))
        for i in sorted(self._tile_bodies.keys() - wanted):
            for body in self._tile_bodies.pop(i):
                self.obstacle_kind.pop(body, None)
                pb.removeBody(body, physicsClientId=self.client)
        for i in sorted(wanted - self._tile_bodies.keys()):
            by_kind: dict[str, list] = {}
            for box in road_obstacles(self.track, i):
                by_kind.setdefault(box.kind, []).append(box)
            self._tile_bodies[i] = [self._add_compound(kind, boxes) for kind, boxes in sorted(by_kind.items())]
        self._contiguous = not wanted or max(wanted) - min(wanted) < len(wanted)

    def _add_compound(self, kind: str, boxes: list) -> int:
        shape = pb.createCollisionShapeArray(
            shapeTypes=[pb.GEOM_BOX] * len(boxes),
            halfExtents=[list(b.half_extents) for b in boxes],
            collisionFramePositions=[list(b.center) for b in boxes],
            collisionFrameOrientations=[pb.getQuaternionFromEuler((0.0, 0.0, b.yaw)) for b in boxes],
            physicsClientId=self.client,
        )
        body = pb.createMultiBody(0, shape, useMaximalCoordinates=True, physicsClientId=self.client)
        pb.changeDynamics(body, -1, activationState=pb.ACTIVATION_STATE_SLEEP, physicsClientId=self.client)
        self.obstacle_kind[body] = kind
        return body

    def add_traffic(self, count: int, length: float, width: float, height: float) -> None:
        """`count` traffic car bodies: static (kinematic) boxes of the given size, of kind `vehicle`, placed by
        `place_traffic`; the vehicle collides with them like with any roadside body."""
        shape = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=[0.5 * length, 0.5 * width, 0.5 * height],
                                        physicsClientId=self.client)
        self._traffic_z = 0.5 * height
        self._traffic_reach = 0.5 * math.sqrt(length * length + width * width + height * height)
        for _ in range(count):
            body = pb.createMultiBody(0, shape, basePosition=[0.0, 0.0, HIDDEN_Z], useMaximalCoordinates=True,
                                      physicsClientId=self.client)
            self.obstacle_kind[body] = "vehicle"
            self.traffic_bodies.append(body)

    def place_traffic(self, poses: dict[int, Pose]) -> None:
        """Move traffic car i's body to poses[i] (its centre on the ground, its heading); the bodies of cars
        not given are put out of reach below the ground."""
        self._traffic_shown = _place_bodies(self._move, self.traffic_bodies, poses, self._traffic_z,
                                            self._traffic_shown)
        self._traffic_poses = dict(poses)

    def traffic_touching(self) -> list[int]:
        """Indices of the traffic cars the vehicle touches now."""
        index = {body: i for i, body in enumerate(self.traffic_bodies)}
        return sorted({index[c[2]] for c in pb.getContactPoints(bodyA=self.vehicle.body_id,
                                                                physicsClientId=self.client) if c[2] in index})

    def step(self) -> None:
        """One physics step (the vehicle's motors were set by its last `actuate`), with its road load."""
        if self.steps % OBSTACLE_UPDATE_STEPS == 0:
            sensed = self.vehicle.sensed
            self.update_obstacles(self.vehicle.pose() if sensed is None else sensed[0])
        self._stepped_traffic = self._traffic_poses
        self.vehicle.apply_road_load()
        pb.stepSimulation(physicsClientId=self.client)
        self.steps += 1
        self.t = self.steps * self.dt

    def contact_kinds(self) -> set[str]:
        """Kinds of bodies the vehicle touches now (curb, barrier, guardrail, divider, tree, vehicle)."""
        if self._out_of_reach():
            if self.verify_skips and self._query_contacts():
                raise RuntimeError(f"a skipped contact query at step {self.steps} had contacts")
            self.skipped += 1
            return set()
        return self._query_contacts()

    def _out_of_reach(self) -> bool:
        """True when the contacts of the last step surely hold no roadside body and no traffic car: the car (its
        bodies' reach about its reference point, as sensed after the last step, plus its motion since the last
        query and `CONTACT_SLACK_M`) within the track's band clear of roadside bodies, the loaded tiles one stretch
        of road, and every traffic car shown during the step beyond the two reaches."""
        sensed = self.vehicle.sensed
        last = self._last_query
        if sensed is None:
            self._last_query = None
            return False
        pose = sensed[0]
        self._last_query = (self.steps, pose)
        if last is None or self.steps - last[0] > CONTACT_SKIP_STEPS or not self._contiguous:
            return False
        reach = self._reach + math.hypot(pose.x - last[1].x, pose.y - last[1].y) + CONTACT_SLACK_M
        if not self.track.band_holds_disc(pose.x, pose.y, reach, self._band):
            return False
        reach += self._traffic_reach
        return all(math.hypot(p.x - pose.x, p.y - pose.y) > reach for p in self._stepped_traffic.values())

    def _query_contacts(self) -> set[str]:
        known = self.obstacle_kind
        return {known[c[2]] for c in pb.getContactPoints(bodyA=self.vehicle.body_id, physicsClientId=self.client)
                if c[2] in known}

    def close(self) -> None:
        """Hand the client back (`physics_clients.release`); the world is not used after."""
        if not self._released:
            self._released = True
            physics_clients.release(self.client)


Move = Callable[[int, Sequence[float], Sequence[float]], None]
"""Sets a body's position and quaternion (x, y, z, w): a client's `resetBasePositionAndOrientation`, or the clone's
`TinyBoxes.move`."""


def _body_reach(client: int, vehicle: PyBulletVehicle, cg_height: float) -> float:
    """The farthest any point of the vehicle's colliders (their bounds as placed, upright) lies from its reference
    point, in 3-D: a bound whatever its attitude, as the point moves with the body."""
    body, ref = vehicle.body_id, vehicle.pose()
    ref_z = pb.getBasePositionAndOrientation(body, physicsClientId=client)[0][2] - cg_height
    corners = [(x, y, z) for link in range(-1, pb.getNumJoints(body, physicsClientId=client))
               for lo, hi in [pb.getAABB(body, link, physicsClientId=client)]
               for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
    return max(math.sqrt((x - ref.x) ** 2 + (y - ref.y) ** 2 + (z - ref_z) ** 2) for x, y, z in corners)


def _client_move(client: int) -> Move:
    """`Move` for the bodies of a PyBullet client."""
    def move(body: int, position: Sequence[float], quaternion: Sequence[float]) -> None:
        pb.resetBasePositionAndOrientation(body, position, quaternion, physicsClientId=client)
    return move


def _place_bodies(move: Move, bodies: list[int], poses: dict[int, Pose], z: float, shown: set[int]) -> set[int]:
    """Put bodies[i] at poses[i] (height z) and the shown bodies without a pose below the ground; the set of
    bodies now shown."""
    for i, p in poses.items():
        move(bodies[i], [p.x, p.y, z], [0.0, 0.0, math.sin(0.5 * p.yaw), math.cos(0.5 * p.yaw)])
    for i in shown - poses.keys():
        move(bodies[i], [0.0, 0.0, HIDDEN_Z], [0.0, 0.0, 0.0, 1.0])
    return set(poses)


class TileStreamer:
    """The track around the car, streamed into a ground canvas and the roadside boxes the camera draws.

    `ground="canvas"` (default): the road surface goes into a `GroundCanvas` that the camera draws by
    homography; the roadside and traffic boxes go to `boxes`, drawn by TinyRenderer's compiled clone (with
    `clone=False`, or where it is not built, they are bodies of a render client TinyRenderer draws, to the same
    bytes). `ground="mesh"`: the tiles are textured meshes TinyRenderer rasterises (the reference the canvas is
    tested against, and several times slower), with the boxes as bodies beside them; the render client is reset
    when its texture budget is spent.
    """

    def __init__(self, track, lighting: Lighting, ahead_m: float = 100.0, behind_m: float = 10.0,
                 ground: str = "canvas", texture_budget: int = 40, clone: bool = True) -> None:
        if ground not in GROUND_MODES:
            raise UserError(f"unknown ground mode {ground!r}; choose one of {', '.join(GROUND_MODES)}")
        self.track = track
        self.ahead = ahead_m
        self.behind = behind_m
        self.budget = texture_budget
        self.canvas = GroundCanvas(track, lighting) if ground == "canvas" else None
        module = tiny_kernel() if clone and self.canvas is not None else None
        self.boxes: TinyBoxes | None = TinyBoxes(module) if module is not None else None
        """The roadside and traffic boxes for TinyRenderer's compiled clone (canvas mode, where it is built); None:
        they are bodies of the render client, drawn by TinyRenderer."""
        self.client: int | None = pb.connect(pb.DIRECT) if self.boxes is None else None
        self._move: Move = self.boxes.move if self.boxes is not None else _client_move(self.client)
        self._tmp = tempfile.TemporaryDirectory(prefix="ld3-tiles-")
        self.loaded: dict[int, list[int]] = {}
        self.textures_loaded = 0
        self.resets = 0
        self._traffic_size: tuple[int, float, float, float] | None = None
        self._traffic_bodies: list[int] = []
        self._traffic_poses: dict[int, Pose] = {}
        self._traffic_shown: set[int] = set()
        self._reset_scene()

    def _reset_scene(self) -> None:
        if self.boxes is not None:
            self.boxes.clear()
        else:
            pb.resetSimulation(physicsClientId=self.client)
        self.loaded.clear()
        self.textures_loaded = 0
        self._traffic_bodies, self._traffic_shown = [], set()
        if self._traffic_size is not None:
            self._add_traffic_bodies(*self._traffic_size)

    def add_traffic(self, count: int, length: float, width: float, height: float) -> None:
        """`count` traffic car boxes the camera sees (kept across resets of the render client), placed by
        `place_traffic`."""
        self._traffic_size = (count, length, width, height)
        self._add_traffic_bodies(count, length, width, height)

    def _add_traffic_bodies(self, count: int, length: float, width: float, height: float) -> None:
        if self.boxes is not None:
            mesh = box_mesh((0.5 * length, 0.5 * width, 0.5 * height), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))
            self._traffic_bodies.extend(self.boxes.add([mesh], TRAFFIC_COLOURS[i % len(TRAFFIC_COLOURS)],
                                                       (0.0, 0.0, HIDDEN_Z)) for i in range(count))
            if self._traffic_poses:
                self.place_traffic(self._traffic_poses)
            return
        shape = pb.createVisualShape(pb.GEOM_BOX, halfExtents=[0.5 * length, 0.5 * width, 0.5 * height],
                                     physicsClientId=self.client)
        for i in range(count):
            body = pb.createMultiBody(baseVisualShapeIndex=shape, basePosition=[0.0, 0.0, HIDDEN_Z],
                                      physicsClientId=self.client)
            pb.changeVisualShape(body, -1, rgbaColor=list(TRAFFIC_COLOURS[i % len(TRAFFIC_COLOURS)]),
                                 physicsClientId=self.client)
            self._traffic_bodies.append(body)
        if self._traffic_poses:
            self.place_traffic(self._traffic_poses)

    def place_traffic(self, poses: dict[int, Pose]) -> None:
        """Move traffic car i's box to poses[i] (its centre on the ground, its heading); the boxes of cars not
        given are hidden below the ground."""
        self._traffic_poses = dict(poses)
        z = 0.5 * self._traffic_size[3] if self._traffic_size is not None else 0.0
        self._traffic_shown = _place_bodies(self._move, self._traffic_bodies, poses, z, self._traffic_shown)

    def update(self, pose: Pose) -> None:
        """Load the tiles within half the window (`behind` + `ahead`) along the road of the point that far ahead of
        the pose along its heading, drop the others. Where the road turns that point is off it and may lie nearest
        another part of a route that comes back beside itself: it is projected aside (the car's next projection
        still walks from the car's own) and its station held between the car's and `ahead` − `behind` beyond."""
        half = 0.5 * (self.ahead + self.behind)
        shift = half - self.behind
        s, _ = self.track.reference.project(pose.x, pose.y)
        centre, _ = self.track.reference.project_aside(pose.x + shift * math.cos(pose.yaw),
                                                       pose.y + shift * math.sin(pose.yaw))
        wanted = set(self.track.tiles_along(min(max(centre, s), s + shift), half, half))
        missing = wanted - self.loaded.keys()
        if self.canvas is None and self.textures_loaded + len(missing) > self.budget:
            self.resets += 1
            self._reset_scene()
            missing = wanted
        for i in sorted(self.loaded.keys() - wanted):
            for body in self.loaded.pop(i):
                if self.boxes is not None:
                    self.boxes.remove(body)
                else:
                    pb.removeBody(body, physicsClientId=self.client)
        for i in sorted(missing):
            self.loaded[i] = self._load_tile(i)
        if self.canvas is not None:
            self.canvas.set_tiles(wanted)

    def _load_tile(self, i: int) -> list[int]:
        if self.canvas is not None:
            return self._add_obstacle_visuals(i)
        verts, uvs, idx = tile_mesh(self.track, i, spacing=MESH_SPACING_M)
        img = tile_texture(self.track, i)
        path = Path(self._tmp.name) / f"tile{i}.png"
        cv2.imwrite(str(path), np.ascontiguousarray(img[:, :, ::-1]))
        tex = pb.loadTexture(str(path), physicsClientId=self.client)
        path.unlink()
        self.textures_loaded += 1
        uvs = np.asarray(uvs, dtype=float).copy()
        uvs[:, 1] = 1.0 - uvs[:, 1]  # tracks puts v = 0 on texture row 0; PyBullet puts it on the last row
        normals = [[0.0, 0.0, 1.0]] * len(verts)
        vs = pb.createVisualShape(pb.GEOM_MESH, vertices=np.asarray(verts).tolist(),
                                  indices=np.asarray(idx).astype(int).tolist(), uvs=np.asarray(uvs).tolist(),
                                  normals=normals, physicsClientId=self.client)
        body = pb.createMultiBody(baseVisualShapeIndex=vs, physicsClientId=self.client)
        pb.changeVisualShape(body, -1, textureUniqueId=tex, rgbaColor=[1, 1, 1, 1], physicsClientId=self.client)
        return [body, *self._add_obstacle_visuals(i)]

    def _add_obstacle_visuals(self, i: int) -> list[int]:
        """One body per kind of roadside obstacle on tile i (TinyRenderer's cost grows with body count).
        Curbs are low enough to be seen as their painted strip in the road texture; they get no 3-D body here."""
        by_kind: dict[str, list] = {}
        for box in road_obstacles(self.track, i):
            if box.kind not in PAINTED_KINDS:
                by_kind.setdefault(box.kind, []).append(box)
        bodies = []
        for kind, boxes in sorted(by_kind.items()):
            colour = OBSTACLE_COLOURS.get(kind, (0.6, 0.6, 0.6, 1.0))
            if self.boxes is not None:
                meshes = [box_mesh(b.half_extents, b.center, pb.getQuaternionFromEuler((0.0, 0.0, b.yaw)))
                          for b in boxes]
                bodies.append(self.boxes.add(meshes, colour))
                continue
            vs = pb.createVisualShapeArray(
                shapeTypes=[pb.GEOM_BOX] * len(boxes), halfExtents=[list(b.half_extents) for b in boxes],
                visualFramePositions=[list(b.center) for b in boxes],
                visualFrameOrientations=[pb.getQuaternionFromEuler((0.0, 0.0, b.yaw)) for b in boxes],
                physicsClientId=self.client)
            body = pb.createMultiBody(baseVisualShapeIndex=vs, physicsClientId=self.client)
            pb.changeVisualShape(body, -1, rgbaColor=list(colour), physicsClientId=self.client)
            bodies.append(body)
        return bodies

    def close(self) -> None:
        if self.client is not None and pb.isConnected(self.client):
            pb.disconnect(self.client)
        self._tmp.cleanup()
