"""The rates of a run (`[rates]`): physics, control, camera, the command hold and the localization sensors' table,
one typed model read by the scenario, the loop and every driver (simulation, HIL, vehicle)."""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, ConfigDict, Field, model_validator

from testbed.localization.stack import LocalizationConfig

PHYSICS_HZ = 80.0
"""Physics steps per second unless `[rates] physics_hz` says otherwise: two steps a 40 Hz control tick, a rate
whose results match 240 Hz (docs/decisions.md)."""

CONTROL_HZ = 40.0
"""Control ticks per second unless `[rates] control_hz` says otherwise (why this rate: docs/decisions.md, the
control rate); the control period everywhere is `Rates.control_dt`."""

CAMERA_HZ = 20.0
"""Camera frames (and lane detections) per second unless `[rates] camera_hz` says otherwise."""

STRICT = ConfigDict(frozen=True, extra="forbid", strict=True, allow_inf_nan=False)
"""How every scenario model reads TOML: no unknown keys, no strings or booleans for numbers, finite numbers."""


class Rates(BaseModel):
    """Physics, control and camera rates (Hz), the command hold of a sampled chassis, and the localization
    sensors' `[rates.localization]` table; the camera runs no faster than control, control no faster than
    physics."""

    model_config = STRICT

    physics_hz: float = Field(PHYSICS_HZ, gt=0, le=10_000, description="physics steps per second (Hz)")
    control_hz: float = Field(CONTROL_HZ, gt=0, description="control loop rate (Hz), at most physics_hz")
    camera_hz: float = Field(CAMERA_HZ, gt=0,
                             description="camera and lane detector rate (Hz), at most control_hz")
    command_hold_s: float = Field(0.0, ge=0, le=1.0, description="sample-and-hold period of chassis commands (s), "
                                                                  "0 = applied at once")
    localization: dict[str, Any] = Field(default_factory=dict,
                                         description="sensor rates (gnss_hz, lidar_hz, imu_hz) and the gnss, "
                                                     "lidar, imu and msf error models and tuning")

    @model_validator(mode="after")
    def _consistent(self) -> Rates:
        if self.control_hz > self.physics_hz:
            raise ValueError(f"rates.control_hz ({self.control_hz:g}) must not exceed rates.physics_hz "
                             f"({self.physics_hz:g}): raise rates.physics_hz with it, e.g. rates.physics_hz="
                             f"{max(self.control_hz, 100.0):g}")
        if self.camera_hz > self.control_hz:
            raise ValueError(f"rates.camera_hz ({self.camera_hz:g}) must not exceed rates.control_hz "
                             f"({self.control_hz:g})")
        every = self.camera_every
        if abs(every * self.camera_hz - self.control_hz) > 1e-6 * self.control_hz:
            raise ValueError(f"rates.camera_hz ({self.camera_hz:g}) must divide rates.control_hz "
                             f"({self.control_hz:g}): a frame every {every} ticks would be "
                             f"{self.control_hz / every:g} Hz; choose a control rate that is a multiple of it")
        loc = LocalizationConfig.from_dict(self.localization)
        for name, hz in (("gnss_hz", loc.gnss_hz), ("lidar_hz", loc.lidar_hz)):
            if hz > self.control_hz:
                raise ValueError(f"rates.localization.{name} ({hz:g}) must not exceed rates.control_hz "
                                 f"({self.control_hz:g}): the fixes between two ticks would be dropped")
        return self

    @property
    def control_dt(self) -> float:
        """The control period (s): one tick of the loop."""
        return 1.0 / self.control_hz

    @property
    def camera_every(self) -> int:
        """The camera delivers a frame every `camera_every`-th control tick."""
        return max(1, round(self.control_hz / self.camera_hz))

    def explicit(self) -> dict[str, Any]:
        """The table as TOML would hold it, defaults left out."""
        return self.model_dump(exclude_defaults=True)
