# cython: language_level=3, boundscheck=False, wraparound=False, initializedcheck=False, cdivision=True
"""`PyBulletVehicle.actuate` and `PyBulletVehicle.sense` compiled: the steering actuator's step, the governor, the
road load and the wheel torques of a command interval; the reference-point pose, speed, yaw rate and bicycle steer
angle read from PyBullet, and the filtered acceleration.

The same PyBullet calls with the same arguments, and the same arithmetic as the pure-Python methods in
`vehicles/pybullet_vehicle.py`, `vehicles/steering.py` and `vehicles/road_load.py`, operation for operation (the
build turns off multiply-add contraction; Python's `min` and `max` as they treat floats; libm's trigonometry, as
Python's `math` calls it), so every command sent and every state sensed is the same to the bit;
`tests/vehicles/test_vehicle_kernels.py` holds it to it. The vehicle's Python state (its command, speed, filtered
acceleration, road load, sent steer, the actuator's angle and rate) is read and written back on every call.
"""

from libc.math cimport NAN, atan, atan2, cos, fabs, sin, tan
from tracks.float_order cimport py_max, py_min

from vehicles import road_load

cdef double GRAVITY = road_load.GRAVITY, AIR_DENSITY = road_load.AIR_DENSITY, SOFT_SPEED = road_load._SOFT_SPEED


cdef class VehicleMotion:
    """Actuation and sensing of one `PyBulletVehicle` (its body, joints and parameters as built) through the
    `pybullet` module `pb` it was built with (so this module imports no simulator), with the vehicle module's
    constants handed in: the governor's gain, the traction slip, the acceleration filter's time constant,
    the steering motors' torque and gains, the wheel motors' velocity gain, and the `Pose` type the pose is reported in."""

    cdef object vehicle, steering, pose_type, steer_ids, wheel_ids, joint_ids, wheel_kv, pb
    cdef int body, cid
    cdef double max_decel, max_accel, max_speed, wheel_radius, front_share, m_eff, crr_mg, drag, wheelbase, half_track
    cdef double governor, slip, filter_tau, steer_torque, steer_kp, steer_kv, ox, oz

    def __init__(self, vehicle, pb, double governor, double slip, double filter_tau, double steer_torque,
                 double steer_kp, double steer_kv, double wheel_kv, pose_type):
        prm = vehicle.params
        self.pb = pb
        self.vehicle, self.steering, self.pose_type = vehicle, vehicle._steering, pose_type
        self.body, self.cid = vehicle.body_id, vehicle._cid
        self.steer_ids, self.wheel_ids = vehicle.steer_joint_ids, vehicle.wheel_link_ids
        self.joint_ids = self.steer_ids + self.wheel_ids
        self.wheel_kv = (wheel_kv,) * 4
        self.max_decel, self.max_accel, self.max_speed = prm.max_decel, prm.max_accel, prm.max_speed
        self.wheel_radius, self.front_share, self.m_eff = prm.wheel_radius, prm.front_brake_share, vehicle._m_eff
        self.crr_mg = prm.rolling_resistance * prm.mass * GRAVITY  # road_load's product, left to right
        self.drag = 0.5 * AIR_DENSITY * prm.drag_area
        self.wheelbase, self.half_track = prm.wheelbase, prm.track_width / 2.0
        self.governor, self.slip, self.filter_tau = governor, slip, filter_tau
        self.steer_torque, self.steer_kp, self.steer_kv = steer_torque, steer_kp, steer_kv
        self.ox, self.oz = vehicle._cg_offset[0], vehicle._cg_offset[2]

    def actuate(self, double dt):
        """`PyBulletVehicle.actuate`."""
        vehicle, steering, p = self.vehicle, self.steering, self.pb
        cdef double v = vehicle._speed, max_angle = steering.max_angle, angle = steering.angle, target, max_step
        cdef double delta, accel, load, force, r = self.wheel_radius, drive, spin, front, rear
        target = py_max(-max_angle, py_min(max_angle, vehicle._cmd_steer))
        max_step = steering.max_rate * dt
        delta = py_max(-max_step, py_min(max_step, target - angle))
        angle += delta
        steering.angle, steering.rate = angle, delta / dt
        cdef bint resend = angle != <double>vehicle._sent_steer
        accel = py_max(-self.max_decel, py_min(py_min(self.max_accel, vehicle._cmd_accel),
                                                 self.governor * (self.max_speed - v)))
        load = self.crr_mg * v / py_max(fabs(v), SOFT_SPEED) + self.drag * v * fabs(v)
        vehicle._load = load
        force = self.m_eff * accel + load
        if force >= 0.0:
            drive = force * r / 2.0
            spin = (py_max(v, 0.0) + self.slip) / r
            if resend:
                self._send_all(angle, (0.0, 0.0, spin, spin), (0.0, 0.0, drive, drive))
                return
            p.setJointMotorControlArray(self.body, self.wheel_ids, p.VELOCITY_CONTROL,
                                        targetVelocities=(0.0, 0.0, spin, spin), forces=(0.0, 0.0, drive, drive),
                                        physicsClientId=self.cid)
        else:
            front = -force * self.front_share * r / 2.0
            rear = -force * (1.0 - self.front_share) * r / 2.0
            if resend:
                self._send_all(angle, (0.0, 0.0, 0.0, 0.0), (front, front, rear, rear))
                return
            p.setJointMotorControlArray(self.body, self.wheel_ids, p.VELOCITY_CONTROL,
                                        targetVelocities=(0.0, 0.0, 0.0, 0.0), forces=(front, front, rear, rear),
                                        physicsClientId=self.cid)

    cdef _send_all(self, double delta, tuple targets, tuple torques):
        """`PyBulletVehicle._send_all`: the front wheels to their Ackermann angles and the wheels' velocity command,
        in one call."""
        cdef double t = tan(delta), left, right, wb = self.wheelbase
        p = self.pb
        left = atan2(wb * t, wb - self.half_track * t)
        right = atan2(wb * t, wb + self.half_track * t)
        p.setJointMotorControlArray(self.body, self.joint_ids, p.POSITION_CONTROL,
                                    targetPositions=(left, right, 0.0, 0.0, 0.0, 0.0),
                                    targetVelocities=(0.0, 0.0) + targets,
                                    forces=(self.steer_torque, self.steer_torque) + torques,
                                    positionGains=(self.steer_kp, self.steer_kp, 0.0, 0.0, 0.0, 0.0),
                                    velocityGains=(self.steer_kv, self.steer_kv) + self.wheel_kv,
                                    physicsClientId=self.cid)
        self.vehicle._sent_steer = delta

    def sense(self, double dt, bint steer=True):
        """`PyBulletVehicle.sense`."""
        vehicle, p = self.vehicle, self.pb
        cdef double px, py, x, y, z, w, yaw, ref_x, ref_y, lx, ly, yaw_rate, v, tl, tr, angle, alpha, speed, acc
        pos, orn = p.getBasePositionAndOrientation(self.body, physicsClientId=self.cid)
        lin, ang = p.getBaseVelocity(self.body, physicsClientId=self.cid)
        px, py = pos[0], pos[1]
        x, y, z, w = orn
        ref_x = px - ((1.0 - 2.0 * (y * y + z * z)) * self.ox + 2.0 * (x * z + y * w) * self.oz)
        ref_y = py - (2.0 * (x * y + z * w) * self.ox + 2.0 * (y * z - x * w) * self.oz)
        yaw = atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
        lx, ly, yaw_rate = lin[0], lin[1], ang[2]
        v = lx * cos(yaw) + ly * sin(yaw)
        if steer:
            left, right = p.getJointStates(self.body, self.steer_ids, physicsClientId=self.cid)
            tl, tr = tan(<double>left[0]), tan(<double>right[0])
            angle = 0.0 if tl + tr == 0.0 else atan(2.0 * tl * tr / (tl + tr))
        else:
            angle = NAN
        vehicle.sensed = (self.pose_type(ref_x, ref_y, yaw), v, yaw_rate, angle)
        speed, acc = vehicle._speed, vehicle._accel
        alpha = dt / (self.filter_tau + dt)
        vehicle._accel = acc + alpha * ((v - speed) / dt - acc)
        vehicle._speed = v
