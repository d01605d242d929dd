"""summary.json as typed models (docs/outputs.md): `RunSummary` for a simulated run, `HilSummary`
for one over CAN, `VehicleSummary` for a drive on a real vehicle. A summary is built once, checked on
construction (no unknown or missing key), and written by `write`; non-finite numbers are written as null."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, ValidationError, field_serializer

from testbed.errors import UserError
from testbed.eval.run.consequence import Consequence
from testbed.traffic.record import HitVehicle

SCHEMA_VERSION = 8
"""Version of summary.json's layout; raised when a key is added, changes meaning or goes away."""


class FaultRecord(BaseModel):
    """A fault the run latched: by the chassis (it ends the run) or handled by the defense."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    kind: str
    source: Literal["chassis", "defense"]
    time: float
    detail: str
    last_time: float | None = None
    count: int | None = None


class RunSummary(BaseModel):
    """One run's summary: provenance, the resolved scenario, the components, timing, deviations, the
    consequence, faults, detection and the attack response."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    schema_version: int = SCHEMA_VERSION
    package_version: str | None
    git_commit: str | None
    resolved_scenario: dict[str, Any]
    scenario: str
    seed: int | None
    track: str
    vehicle: str
    attack: dict[str, Any] | list[dict[str, Any]] | None
    threat_model: str
    defense: str
    defense_params: dict[str, Any] | None = None
    condition: str
    detector: str
    tracking: bool | None = None
    localization: str
    target_speed_mps: float | None = None
    sim_time_s: float
    wall_time_s: float
    real_time_factor: float | None
    lane_width_m: float
    lane_straddle_dev_m: float | None
    max_abs_dev_m: float | None
    final_dev_m: float | None
    consequence: Consequence
    ended_by: Literal["consequence", "standstill", "road_end", "duration"] | None = None
    """What ended the run: a run-ending consequence, standstill after a stop, the end of the road, or the
    scenario's duration (a `reach_destination` that ran out of time short of the road's end); None: not over."""
    faults: list[FaultRecord]
    detected: bool
    detection_time_s: float | None
    detection_dev_m: float | None
    alarm_check: str | None = None
    """Which of the defense's checks raised the alarm (LD3: `lateral-lines`, `lateral-odometry`, `lateral-unplaced`,
    `heading-lines`, `heading-odometry`, `along-odometry`); None without an alarm or for a defense with one check."""
    ar_max_dev_m: float | None
    ar_stop_dev_m: float | None
    stop_time_s: float | None
    attack_state: Any = None
    traffic_vehicles: int | None = None
    """Traffic cars on the road (None: an empty road)."""
    hit_vehicle: HitVehicle | None = None
    """The traffic car the ego hit (consequence `hit_vehicle`), else None."""
    odometry_bias_rad_per_m: float | None = None
    """Odometry's yaw-rate error per metre travelled as the defense estimated it at the end (rad/m; fail-closed
    LD3): tan δ₀ / L for a steering sensor δ₀ off in a yaw rate derived from it. None: no estimate."""

    @field_serializer("faults")
    def _faults(self, faults: list[FaultRecord]) -> list[dict[str, Any]]:
        """A chassis fault has no repeat count: its record leaves those keys out."""
        return [f.model_dump(exclude_none=True) for f in faults]

    def as_dict(self) -> dict[str, Any]:
        """The summary as a plain dict (what the Python API, `testbed.api`, hands out)."""
        return self.model_dump()

    def write(self, path: Path) -> None:
        path.write_text(json.dumps(_json_safe(self.model_dump(mode="python")), indent=2) + "\n")


class CanLinkFields(BaseModel):
    """What a run over a CAN link adds: the interface, the profile, the frame counts and the CAN log."""

    interface: str
    profile: str
    can_log: str | None
    can_frames_tx: int
    can_frames_rx: int
    yaw_rate_source: str
    """Where the loop's yaw rate came from: the chassis's report, or derived from what the chassis reports."""


class HilSummary(RunSummary, CanLinkFields):
    """A simulated run with the CAN bridge as its chassis (`ld3 hil`): the consequence and every deviation figure
    of `RunSummary` are judged on the pose `consequence_basis` names; odometry's own figures are kept beside."""

    channel: str | None
    clock: str
    pose_source: str
    consequence_basis: Literal["plant", "odometry"]
    """The pose the consequence and the deviation figures are judged on: the emulated plant's own (its truth, where
    the run's emulator gives it), else the bridge's odometry (the pose the loop's simulated sensors read)."""
    odometry_max_abs_dev_m: float | None
    """max |D| of the bridge's odometry pose, whatever the basis."""
    odometry_final_dev_m: float | None
    """Final D of the bridge's odometry pose, whatever the basis."""
    odometry_error_max_m: float | None
    odometry_error_final_m: float | None
    can_frames_rejected: int
    can_frames_logged: int
    sensors: str
    nmea_fixes: int | None = None
    nmea_bad: int | None = None
    nmea_no_fix: int | None = None
    camera_frames: int | None = None


class VehicleSummary(RunSummary, CanLinkFields):
    """A drive on a real vehicle (`ld3 vehicle`): no truth, so deviations from the lane are the MSF's."""

    lane: int
    max_abs_msf_dev_m: float | None
    consequence_basis: Literal["estimated"] = "estimated"
    """The consequence is judged on the estimated (MSF) pose: a vehicle has no ground truth."""
    rates: dict[str, Any]
    """The loop's rates, `[rates]` as run."""
    nmea_fixes: int
    nmea_bad: int
    nmea_no_fix: int
    nmea_refused: dict[str, int]
    """GGA sentences with a fix that were refused, by reason (hdop, position, time)."""
    gnss_fixes_refused: int
    """GNSS fixes the localization refused (unusable, or outside the MSF's gate)."""
    camera_frames: int
    loop_scheduling: str
    """How the loop's thread was scheduled (`SCHED_FIFO N`, or normal and why; `hil.link.scheduling`)."""
    command_pacer: str
    """How the bridge's command pacer thread was scheduled, as `loop_scheduling`."""


def _json_safe(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json_safe(v) for v in value]
    return value


def _refuse_constant(name: str) -> None:
    raise ValueError(f"{name} is not a number a summary holds (non-finite numbers are written as null)")


def read_summary_object(path: Path) -> dict[str, Any]:
    """The JSON object a run's summary.json holds, its fields unchecked; a file that cannot be read, is not JSON,
    holds a non-finite number (`write` writes those as null) or holds no JSON object is a one-line UserError
    naming it."""
    try:
        data = json.loads(path.read_text(), parse_constant=_refuse_constant)
    except (UnicodeDecodeError, json.JSONDecodeError, ValueError) as exc:
        raise UserError(f"{path} is not readable JSON: {exc}") from None
    except OSError as exc:
        raise UserError(f"cannot read {path}: {exc.strerror}") from None
    if not isinstance(data, dict):
        raise UserError(f"{path} is not a run's summary (not a JSON object)")
    return data


def summary_from(data: dict[str, Any], source: Path) -> RunSummary:
    """`data` (a summary.json's object) as its typed summary: a `VehicleSummary` for a drive on a vehicle, a
    `HilSummary` for a run over CAN, else a `RunSummary`; a field missing, unknown or of the wrong type is a
    one-line UserError naming `source` and the field."""
    kind = (VehicleSummary if data.get("consequence_basis") == "estimated" else HilSummary if "interface" in data
            else RunSummary)
    try:
        return kind.model_validate(data)
    except ValidationError as exc:
        first = exc.errors()[0]
        field = ".".join(str(part) for part in first["loc"]) or "the summary"
        more = f" (and {exc.error_count() - 1} more)" if exc.error_count() > 1 else ""
        raise UserError(f"{source} is not a run summary of this version: {field}: {first['msg']}{more}") from None


def read_summary(path: Path) -> RunSummary:
    """The typed summary a run's summary.json holds (`summary_from`); any problem is a one-line UserError
    naming the file."""
    return summary_from(read_summary_object(path), path)
