"""The scenario's `[traffic]`: how many cars, in which lanes (oncoming lanes of a two-way road too), where they
start relative to the ego car, their desired speeds and gaps (drawn from the run's traffic stream) and their IDM
parameters."""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, Field, model_validator

from testbed.control.idm import IdmParams
from testbed.presets import VEHICLES
from testbed.rates import STRICT


class TrafficConfig(BaseModel):
    """Cars spread round-robin over `lanes`; in the ego lane and in each oncoming lane the first starts `ahead` m
    in front of the ego car, in the others `beside` m ahead of the ego's start (negative: behind), each next one a
    drawn gap further from the ego. A table that would place no car (vehicles = 0 with other keys changed) is
    refused."""

    model_config = STRICT

    vehicles: int = Field(0, ge=0, le=60, description="number of traffic cars (0 = an empty road)")
    speed: float | None = Field(None, ge=0, le=60, description="mean desired speed of the cars (m/s; default: "
                                                               "the scenario's speed; 0 = parked cars)")
    start_speed: float | None = Field(None, ge=0, le=60, description="speed every car starts at (m/s; default: "
                                                                     "its desired speed; 0 = at rest, like the "
                                                                     "ego car)")
    speed_spread: float = Field(1.0, ge=0, le=20, description="each car's desired speed is drawn uniformly "
                                                              "within speed ± this (m/s), never below 0")
    lanes: list[int] | None = Field(None, description="lanes that carry traffic, 0 = rightmost "
                                                                    "(default: every lane of the track)")
    ahead: float = Field(30.0, ge=1, le=2000, description="gap from the ego car's front to the rear of the first "
                                                          "car in the ego lane and in each oncoming lane (m)")
    beside: float = Field(-5.0, ge=-200, le=2000, description="start of the first car in each other lane, ahead "
                                                              "of the ego's start (m; 0 = beside, < 0 behind)")
    gap: float = Field(40.0, gt=0, le=2000, description="mean bumper-to-bumper gap between consecutive cars in "
                                                        "a lane (m)")
    gap_spread: float = Field(0.25, ge=0, lt=1, description="each gap is drawn uniformly within gap × (1 ± "
                                                            "this)")
    vehicle: str = Field("sedan", description="vehicle whose footprint the cars have")
    accel: float = Field(IdmParams.accel, gt=0, le=10, description="IDM maximum acceleration a (m/s²)")
    decel: float = Field(IdmParams.decel, gt=0, le=10, description="IDM comfortable deceleration b (m/s²)")
    headway: float = Field(IdmParams.headway, ge=0, le=10, description="IDM time headway T (s)")
    min_gap: float = Field(IdmParams.min_gap, ge=0, le=50, description="IDM jam distance s0 (m)")
    ego_follows: bool = Field(False, description="the ego car brakes for the nearest car ahead in its lane (IDM's "
                                                 "braking term on the true gap, as adaptive cruise on a range "
                                                 "sensor); false: it keeps its cruise speed and can run into it")

    @model_validator(mode="after")
    def _can_act(self) -> TrafficConfig:
        if self.vehicle not in VEHICLES:
            raise ValueError(f"traffic.vehicle {self.vehicle!r} unknown; known: {', '.join(VEHICLES.names())}")
        if self.lanes == []:
            raise ValueError("traffic.lanes is empty: name the lanes that carry traffic, or leave it out for all")
        if self.lanes is not None and len(set(self.lanes)) != len(self.lanes):
            raise ValueError(f"traffic.lanes {self.lanes} names a lane twice")
        if self.start_speed and self.speed == 0:
            raise ValueError(f"traffic.start_speed = {self.start_speed:g} m/s, but traffic.speed = 0 parks the cars: "
                             f"drop traffic.start_speed or set traffic.speed")
        changed = sorted(k for k, f in type(self).model_fields.items() if k != "vehicles"
                         and getattr(self, k) != f.get_default(call_default_factory=True))
        if self.vehicles == 0 and changed:
            raise ValueError(f"traffic.vehicles = 0, so traffic.{', traffic.'.join(changed)} would change "
                             f"nothing: set traffic.vehicles or remove them")
        return self

    def idm(self) -> IdmParams:
        """The cars' IDM parameters."""
        return IdmParams(accel=self.accel, decel=self.decel, headway=self.headway, min_gap=self.min_gap)

    def explicit(self) -> dict[str, Any]:
        """The table as TOML would hold it, defaults left out."""
        return self.model_dump(exclude_defaults=True)
