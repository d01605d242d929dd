"""The localization stack the loop steps at the control rate: sensors → (attacker) → MSF → estimate.

Each tick: the IMU propagates the MSF; a due GNSS fix passes through the attacker's spoofer (if any) and
the stack's `gnss_port` (if any) and updates the MSF; a due LiDAR fix, searched from the MSF prediction,
updates it. `GroundTruthLocalization` is the same contract returning the true pose, for runs that do not
exercise localization.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from testbed.chassis import ChassisState
from testbed.localization.estimate import LocalizationEstimate
from testbed.localization.msf import MsfParams, MultiSensorFusion
from testbed.localization.sensors import (
    GnssFix,
    GnssModel,
    GnssSensor,
    Imu,
    ImuModel,
    ImuSample,
    LidarLocator,
    LidarModel,
)
from testbed.params import ParamsError
from tracks.compiled import compiled_module
from tracks.pose import Pose

_KERNELS = compiled_module("testbed.localization.msf_kernels")

GnssSpoofer = Callable[[GnssFix], GnssFix]
GnssPort = Callable[[GnssFix], GnssFix | None]
"""A fix's way from the receiver to the MSF (sensor-level HIL: out as NMEA, back through the reader); None:
the fix did not arrive."""


def _section(cls: type, values: Any, name: str) -> Any:
    if not isinstance(values, Mapping):
        raise ParamsError(f"localization.{name} must be a table, got {values!r}")
    known = {f.name: f for f in dataclasses.fields(cls)}
    unknown = sorted(set(values) - set(known))
    if unknown:
        raise ParamsError(f"unknown localization.{name} parameter(s) {unknown}; known: {sorted(known)}")
    kwargs: dict[str, Any] = {}
    for key, raw in values.items():
        default = getattr(cls(), key)
        if isinstance(default, tuple):
            if not (
                isinstance(raw, list | tuple)
                and len(raw) == 2
                and all(_is_num(v) for v in raw)
                and 0 <= raw[0] <= raw[1]
            ):
                raise ParamsError(
                    f"localization.{name}.{key} must be a pair [low, high] with 0 <= low <= high"
                )
            kwargs[key] = (float(raw[0]), float(raw[1]))
        else:
            if not _is_num(raw) or raw < 0:
                raise ParamsError(f"localization.{name}.{key} must be a number >= 0, got {raw!r}")
            kwargs[key] = float(raw)
    return cls(**kwargs)


def _is_num(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and np.isfinite(v)


@dataclass(frozen=True)
class LocalizationConfig:
    """Sensor rates and error models plus MSF tuning; `from_dict` reads a [localization] table."""

    gnss_hz: float = 10.0
    lidar_hz: float = 10.0
    imu_hz: float = 100.0
    gnss: GnssModel = field(default_factory=GnssModel)
    lidar: LidarModel = field(default_factory=LidarModel)
    imu: ImuModel = field(default_factory=ImuModel)
    msf: MsfParams = field(default_factory=MsfParams)

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> LocalizationConfig:
        sections = {"gnss": GnssModel, "lidar": LidarModel, "imu": ImuModel, "msf": MsfParams}
        rates = ("gnss_hz", "lidar_hz", "imu_hz")
        unknown = sorted(set(d) - set(sections) - set(rates))
        if unknown:
            raise ParamsError(
                f"unknown localization parameter(s) {unknown}; known: {sorted([*rates, *sections])}"
            )
        kwargs: dict[str, Any] = {}
        for key in rates:
            if key in d:
                if not _is_num(d[key]) or d[key] <= 0:
                    raise ParamsError(f"localization.{key} must be a number > 0, got {d[key]!r}")
                kwargs[key] = float(d[key])
        for key, model in sections.items():
            if key in d:
                kwargs[key] = _section(model, d[key], key)
        cfg = cls(**kwargs)
        if not 0.0 < cfg.msf.gate_prob < 1.0:
            raise ParamsError(f"localization.msf.gate_prob must be in (0, 1), got {cfg.msf.gate_prob}")
        return cfg


class Localization(Protocol):
    """A localization source the loop steps at the control rate: the estimate at t, and the GNSS fix it
    fused on that step (None if none was due, or it fuses no GNSS)."""

    last_gnss: GnssFix | None

    def step(self, t: float, truth: ChassisState, spoof_gnss: GnssSpoofer | None = None) -> LocalizationEstimate:
        ...


class LocalizationStack:
    """GNSS, LiDAR locator and IMU models feeding one MSF; `step` is called at the control rate. The IMU
    samples at its own rate: a slower control tick hands the MSF every IMU sample due since the last tick, with
    the motion the tick read (GNSS and LiDAR fixes are due no faster than the control rate: `[rates]`)."""

    def __init__(
        self,
        config: LocalizationConfig,
        rng: np.random.Generator,
        feature_quality: Callable[[float, float], float],
        start_pose: Pose,
        start_speed: float,
    ) -> None:
        self.config = config
        self.gnss = GnssSensor(rng, config.gnss_hz, config.gnss)
        self.lidar = LidarLocator(rng, feature_quality, config.lidar_hz, config.lidar)
        self.imu = Imu(rng, config.imu_hz, config.imu)
        self.msf = MultiSensorFusion(start_pose, start_speed, config.msf)
        self.last_gnss: GnssFix | None = None
        self.gnss_port: GnssPort | None = None
        """Where a fix goes between the receiver (and attacker) and the MSF; None: straight in."""
        self._imu_step = (None if _KERNELS is None or self.msf._predictor is None
                          else _KERNELS.ImuPropagation(self.imu, self.msf, ImuSample))
        """The IMU's samples and the MSF's propagation with them compiled (testbed/localization/msf_kernels.pyx),
        where built; None: `Imu.samples` and `MultiSensorFusion.predict`, the reference it is tested equal to."""

    def step(
        self, t: float, truth: ChassisState, spoof_gnss: GnssSpoofer | None = None
    ) -> LocalizationEstimate:
        if truth.true_pose is None:
            raise ValueError(
                "LocalizationStack simulates its sensors from the true pose; ChassisState has none"
            )
        pose = truth.true_pose
        if self._imu_step is not None:
            self._imu_step.step(t, truth.accel, truth.body_yaw_rate)
        else:
            # the tick's motion held since the last
            for sample in self.imu.samples(t, truth.accel, truth.body_yaw_rate):
                self.msf.predict(sample)
        self.last_gnss = None
        if self.gnss.due(t):
            fix = self.gnss.measure(t, pose)
            if spoof_gnss is not None:
                fix = spoof_gnss(fix)
            if self.gnss_port is not None:
                fix = self.gnss_port(fix)
            self.last_gnss = fix
            if fix is not None:
                self.msf.update_gnss(fix)
        if self.lidar.due(t):
            self.msf.update_lidar(self.lidar.measure(t, pose, prior=self.msf.pose))
        return self.msf.estimate(t)


class GroundTruthLocalization:
    """The true pose with a tiny covariance: the same `step` contract as `LocalizationStack`."""

    def __init__(self, std: float = 0.01) -> None:
        self.cov = np.diag([std * std, std * std, (0.1 * std) ** 2])
        self.last_gnss: GnssFix | None = None

    def step(
        self, t: float, truth: ChassisState, spoof_gnss: GnssSpoofer | None = None
    ) -> LocalizationEstimate:
        if truth.true_pose is None:
            raise ValueError("GroundTruthLocalization needs ChassisState.true_pose")
        return LocalizationEstimate(t, truth.true_pose, self.cov.copy())
