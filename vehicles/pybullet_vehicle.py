"""The vehicle as a PyBullet multibody driven through its wheels: physics does the driving.

Once per command interval of `dt` s (`actuate`, the motors then hold their targets for the physics steps
in it), the rate-limited steering advances towards its command by dt and the two Ackermann front wheels
are sent to the angles it reaches at the interval's end (position control), and the acceleration
command becomes wheel torques from the speed measured at the interval's start: F = m_eff·a + road_load(v)
with m_eff = m + ΣI_wheel/r²; F > 0 drives the rear wheels (velocity motors at that torque limit, their
target capped 1 m/s above the body speed as traction control), F < 0 brakes all four (velocity motors
held at 0 rad/s with the brake torque as their limit, i.e. Coulomb-like brakes that hold a stopped car).
The road load is pushed on the body as an external force every physics step (`apply_road_load`). A speed
governor caps the command at (max_speed − v)·2 s⁻¹. `sense` measures the speed after each interval and
low-pass filters its change into the reported acceleration. The car is only placed by `reset_pose`,
never teleported"""

from __future__ import annotations

import math
import tempfile
from pathlib import Path

import pybullet as p

from tracks.compiled import compiled_module
from tracks.pose import Pose
from vehicles.params import VehicleParams
from vehicles.road_load import road_load
from vehicles.steering import SteeringActuator, ackermann_angles, bicycle_angle
from vehicles.urdf import STATIC_DEFLECTION, STEER_JOINT_NAMES, WHEEL_NAMES, write_urdf

DEFAULT_URDF_DIR = Path(tempfile.gettempdir()) / "ld3_vehicles"
_GOVERNOR_GAIN = 2.0  # 1/s
_ACCEL_FILTER_TAU = 0.05  # s
_TRACTION_SLIP = 1.0  # m/s: traction control caps the driven rims this much above the body speed
_MAX_WHEEL_SPEED = 400.0  # rad/s, PyBullet's joint velocity cap (default 100 rad/s is too low)
_STEER_TORQUE = 1.0e4  # N·m
_STEER_POSITION_GAIN = 1.0
_STEER_VELOCITY_GAIN = 1.0
_WHEEL_VELOCITY_GAIN = 1.0  # PyBullet's velocity gain of a VELOCITY_CONTROL motor command that gives none
_ORIGIN = (0.0, 0.0, 0.0)
_KERNELS = compiled_module("vehicles.vehicle_kernels")


def _yaw_of(q: tuple[float, float, float, float]) -> float:
    x, y, z, w = q
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def _longitudinal(lin: tuple[float, ...], yaw: float) -> float:
    """The world-frame velocity `lin` along the heading `yaw`."""
    return lin[0] * math.cos(yaw) + lin[1] * math.sin(yaw)


class PyBulletVehicle:
    """A `VehicleParams` car loaded into an existing PyBullet client; reports the reference-point pose."""

    def __init__(
        self,
        client_id: int,
        params: VehicleParams,
        pose: Pose,
        urdf_dir: str | Path | None = None,
    ) -> None:
        self.params = params
        self._cid = client_id
        path = write_urdf(params, urdf_dir if urdf_dir is not None else DEFAULT_URDF_DIR)
        self.body_id: int = p.loadURDF(
            str(path), flags=p.URDF_USE_INERTIA_FROM_FILE, physicsClientId=client_id
        )
        joints = {
            p.getJointInfo(self.body_id, j, physicsClientId=client_id)[1].decode(): j
            for j in range(p.getNumJoints(self.body_id, physicsClientId=client_id))
        }
        self.wheel_link_ids: tuple[int, ...] = tuple(joints[f"spin_{n}"] for n in WHEEL_NAMES)
        self.steer_joint_ids: tuple[int, ...] = tuple(joints[n] for n in STEER_JOINT_NAMES)
        p.changeDynamics(self.body_id, -1, linearDamping=0.0, angularDamping=0.0, physicsClientId=client_id)
        for j in self.wheel_link_ids:
            p.changeDynamics(self.body_id, j, maxJointVelocity=_MAX_WHEEL_SPEED, physicsClientId=client_id)

        r = params.wheel_radius
        i_spin = params.wheel_mass * r * r / 2.0
        self._m_eff = params.mass + 4.0 * i_spin / (r * r)
        self._cg_offset = (params.cg_x, 0.0, params.cg_height)
        self._steering = SteeringActuator(params.max_steer, params.max_steer_rate)
        self._cmd_steer = 0.0
        self._cmd_accel = 0.0
        self._sent_steer = 0.0
        self._load = 0.0
        self._speed = 0.0
        self._accel = 0.0
        self.sensed: tuple[Pose, float, float, float] | None = None
        """(pose, speed, yaw rate, steer angle) as `sense` measured them; None once physics has stepped since."""
        self._motion = None if _KERNELS is None else _KERNELS.VehicleMotion(
            self, p, _GOVERNOR_GAIN, _TRACTION_SLIP, _ACCEL_FILTER_TAU, _STEER_TORQUE, _STEER_POSITION_GAIN,
            _STEER_VELOCITY_GAIN, _WHEEL_VELOCITY_GAIN, Pose)
        """`actuate` and `sense` compiled (vehicles/vehicle_kernels.pyx), where built; None: the methods below,
        the reference it is tested equal to."""
        self.reset_pose(pose)

    # -- commands and actuation -----------------------------------------------------------------------

    def apply(self, steer_cmd: float, accel_cmd: float) -> None:
        """Store the command: road-wheel angle (rad, + left) and longitudinal accel (m/s², < 0 brakes)."""
        self._cmd_steer = steer_cmd
        self._cmd_accel = accel_cmd

    def actuate(self, dt: float) -> None:
        """Hand the stored command to PyBullet's motors for the next `dt` s of physics (once per command
        interval; the motors keep their targets across the physics steps in it)."""
        if self._motion is not None:
            self._motion.actuate(dt)
            return
        prm, v = self.params, self._speed
        delta = self._steering.step(self._cmd_steer, dt)
        accel = max(-prm.max_decel, min(prm.max_accel, self._cmd_accel, _GOVERNOR_GAIN * (prm.max_speed - v)))
        self._load = road_load(prm, v)
        force = self._m_eff * accel + self._load
        r = prm.wheel_radius
        if force >= 0.0:
            drive = force * r / 2.0
            spin = (max(v, 0.0) + _TRACTION_SLIP) / r
            targets = (0.0, 0.0, spin, spin)
            torques = (0.0, 0.0, drive, drive)
        else:
            front = -force * prm.front_brake_share * r / 2.0
            rear = -force * (1.0 - prm.front_brake_share) * r / 2.0
            targets = (0.0, 0.0, 0.0, 0.0)
            torques = (front, front, rear, rear)
        if delta != self._sent_steer:  # motors keep their targets: resend on change
            self._send_all(delta, targets, torques)
            return
        p.setJointMotorControlArray(
            self.body_id,
            self.wheel_link_ids,
            p.VELOCITY_CONTROL,
            targetVelocities=targets,
            forces=torques,
            physicsClientId=self._cid,
        )

    def apply_road_load(self) -> None:
        """Push the road load of the last `actuate` on the body, along its x axis at its centre of mass, for
        the next physics step (PyBullet clears external forces after every step); `sensed` is stale after it."""
        self.sensed = None
        p.applyExternalForce(self.body_id, -1, (-self._load, 0.0, 0.0), _ORIGIN, p.LINK_FRAME,
                             physicsClientId=self._cid)

    def sense(self, dt: float, steer: bool = True) -> None:
        """Measure the state after `dt` s of physics since the last `sense` (kept in `sensed` until the next
        physics step) and update the filtered accel from its speed; without `steer` the road-wheel angle is not
        read (NaN in `sensed`: one PyBullet state read less, for a port whose state reports none)."""
        if self._motion is not None:
            self._motion.sense(dt, steer)
            return
        pose, v, yaw_rate = self.kinematics()
        self.sensed = (pose, v, yaw_rate, self.steer_angle() if steer else math.nan)
        alpha = dt / (_ACCEL_FILTER_TAU + dt)
        self._accel += alpha * ((v - self._speed) / dt - self._accel)
        self._speed = v

    def _send_steer(self, delta: float) -> None:
        """Front wheels to their Ackermann angles for `delta` (the position motors reach them within a step)."""
        left, right = ackermann_angles(delta, self.params.wheelbase, self.params.track_width)
        p.setJointMotorControlArray(
            self.body_id,
            self.steer_joint_ids,
            p.POSITION_CONTROL,
            targetPositions=(left, right),
            forces=(_STEER_TORQUE, _STEER_TORQUE),
            positionGains=(_STEER_POSITION_GAIN, _STEER_POSITION_GAIN),
            velocityGains=(_STEER_VELOCITY_GAIN, _STEER_VELOCITY_GAIN),
            physicsClientId=self._cid,
        )
        self._sent_steer = delta

    def _send_all(self, delta: float, targets: tuple[float, ...], torques: tuple[float, ...]) -> None:
        """`_send_steer(delta)` and the wheels' velocity command in one PyBullet call: the wheels' motors as a
        velocity command leaves them (position target 0 at gain 0, `_WHEEL_VELOCITY_GAIN`), each motor's state
        the same as after the two calls."""
        left, right = ackermann_angles(delta, self.params.wheelbase, self.params.track_width)
        p.setJointMotorControlArray(
            self.body_id,
            self.steer_joint_ids + self.wheel_link_ids,
            p.POSITION_CONTROL,
            targetPositions=(left, right, 0.0, 0.0, 0.0, 0.0),
            targetVelocities=(0.0, 0.0, *targets),
            forces=(_STEER_TORQUE, _STEER_TORQUE, *torques),
            positionGains=(_STEER_POSITION_GAIN, _STEER_POSITION_GAIN, 0.0, 0.0, 0.0, 0.0),
            velocityGains=(_STEER_VELOCITY_GAIN, _STEER_VELOCITY_GAIN) + (_WHEEL_VELOCITY_GAIN,) * 4,
            physicsClientId=self._cid,
        )
        self._sent_steer = delta

    def reset_pose(self, pose: Pose, speed: float = 0.0) -> None:
        """Place the car (initial placement only) at `pose`, straight wheels, rolling forward at `speed`."""
        cid, body = self._cid, self.body_id
        c, s = math.cos(pose.yaw), math.sin(pose.yaw)
        ox, _, oz = self._cg_offset
        com = (pose.x + c * ox, pose.y + s * ox, oz - STATIC_DEFLECTION)
        p.resetBasePositionAndOrientation(
            body, com, p.getQuaternionFromEuler((0.0, 0.0, pose.yaw)), physicsClientId=cid
        )
        p.resetBaseVelocity(body, (speed * c, speed * s, 0.0), (0.0, 0.0, 0.0), physicsClientId=cid)
        for j in self.steer_joint_ids:
            p.resetJointState(body, j, 0.0, 0.0, physicsClientId=cid)
        for j in self.wheel_link_ids:
            p.resetJointState(body, j, 0.0, speed / self.params.wheel_radius, physicsClientId=cid)
        self._steering.reset(0.0)
        self._send_steer(0.0)
        self._cmd_steer = 0.0
        self._cmd_accel = 0.0
        self._speed = speed
        self._accel = 0.0
        self._load = 0.0
        self.sensed = None

    # -- measurements ---------------------------------------------------------------------------------

    def pose(self) -> Pose:
        """Reference point (footprint centre projected on the ground) and heading, world frame."""
        return self._pose(*p.getBasePositionAndOrientation(self.body_id, physicsClientId=self._cid))

    def _pose(self, pos: tuple[float, ...], orn: tuple[float, ...]) -> Pose:
        (px, py, _), (x, y, z, w) = pos, orn
        ox, _, oz = self._cg_offset
        ref_x = px - ((1.0 - 2.0 * (y * y + z * z)) * ox + 2.0 * (x * z + y * w) * oz)
        ref_y = py - (2.0 * (x * y + z * w) * ox + 2.0 * (y * z - x * w) * oz)
        return Pose(ref_x, ref_y, _yaw_of((x, y, z, w)))

    def speed(self) -> float:
        """Signed longitudinal speed (m/s, + forward)."""
        _, orn = p.getBasePositionAndOrientation(self.body_id, physicsClientId=self._cid)
        lin, _ = p.getBaseVelocity(self.body_id, physicsClientId=self._cid)
        return _longitudinal(lin, _yaw_of(orn))

    def yaw_rate(self) -> float:
        """Yaw rate (rad/s, + counter-clockwise)."""
        return p.getBaseVelocity(self.body_id, physicsClientId=self._cid)[1][2]

    def kinematics(self) -> tuple[Pose, float, float]:
        """`pose()`, `speed()` and `yaw_rate()` from one read of the base's state."""
        pos, orn = p.getBasePositionAndOrientation(self.body_id, physicsClientId=self._cid)
        lin, ang = p.getBaseVelocity(self.body_id, physicsClientId=self._cid)
        pose = self._pose(pos, orn)
        return pose, _longitudinal(lin, pose.yaw), ang[2]

    def accel(self) -> float:
        """Measured longitudinal acceleration (m/s²), low-pass filtered with a 50 ms time constant."""
        return self._accel

    def steer_angle(self) -> float:
        """Actual road-wheel angle (rad, + left): the bicycle-model equivalent of both front wheels."""
        left, right = p.getJointStates(self.body_id, self.steer_joint_ids, physicsClientId=self._cid)
        return bicycle_angle(left[0], right[0])

    def wheel_speeds(self) -> tuple[float, ...]:
        """Rim speeds ω·r (m/s) of the wheels in `wheel_link_ids` order: FL, FR, RL, RR."""
        states = p.getJointStates(self.body_id, self.wheel_link_ids, physicsClientId=self._cid)
        return tuple(st[1] * self.params.wheel_radius for st in states)
