"""profile.toml as typed models: every table, key, unit and range of a chassis profile, checked before its DBC
is opened (`hil.link.profile` then checks the names against the DBC). Unknown keys are refused; values in ms and
degrees are as the file writes them."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import (
    AfterValidator,
    BaseModel,
    ConfigDict,
    Field,
    ValidationInfo,
    create_model,
    field_validator,
    model_validator,
)

REPORT_QUANTITIES = (
    "speed", "accel", "steer", "yaw_rate", "gear", "mode", "estop", "brake_pct", "throttle_pct",
    "emergency_active", "steer_limited", "comm_fault_level", "bad_checksum_count", "bad_counter_count",
    "bad_format_count", "bad_freshness_count", "bad_mac_count", "wheel_rpm_rl", "wheel_rpm_rr",
)
REQUIRED_REPORTS = ("speed", "steer", "mode")
ESTOP_SOURCES = (
    "none", "command_timeout", "bad_frames", "foreign_node", "emergency_brake_command", "chassis_button",
)
GEARS = ("no_request", "park", "reverse", "neutral", "drive")
MODES = ("standby", "self_driving", "remote", "manual")
MAC_BITS, FRESHNESS_BITS = (16, 64), (2, 16)  # the lengths [secoc] accepts

Positive = Annotated[float, Field(gt=0)]
SignalRefText = Annotated[str, Field(pattern=r"^[^.]+\.[^.]+$")]
"""A signal written "Message.Signal"."""


class Table(BaseModel):
    """A profile.toml table: frozen, no unknown keys, no strings or booleans for numbers, finite numbers."""

    model_config = ConfigDict(frozen=True, extra="forbid", strict=True, allow_inf_nan=False)


class TimingTable(Table):
    cycle_ms: Positive
    command_timeout_ms: Positive
    report_timeout_ms: Positive

    @field_validator("command_timeout_ms")
    @classmethod
    def _at_least_a_cycle(cls, value: float, info: ValidationInfo) -> float:
        if value < info.data.get("cycle_ms", 0.0):
            raise ValueError("shorter than one cycle")
        return value


class LongitudinalTable(Table):
    full_throttle_accel: Positive
    full_brake_decel: Positive
    max_accel: Positive
    max_decel: Positive
    fault_decel: Positive

    @field_validator("max_accel", "max_decel")
    @classmethod
    def _within_the_wire_scale(cls, value: float, info: ValidationInfo) -> float:
        scale = "full_throttle_accel" if info.field_name == "max_accel" else "full_brake_decel"
        if value > info.data.get(scale, float("inf")):
            raise ValueError(f"exceeds {scale}")
        return value


class SteeringTable(Table):
    ratio: Positive
    positive: Literal["left", "right"] = "left"
    max_angle_deg: Positive
    max_rate_deg_s: Positive


class CommandTable(Table):
    """One command message and its fixed signal values."""

    message: str
    enable: str
    constants: dict[str, float] = Field(default_factory=dict)


class DriveTable(CommandTable):
    gear: str
    throttle: str


class BrakeTable(CommandTable):
    pedal: str
    emergency: str | None = None


class SteerTable(CommandTable):
    angle: str
    rate: str | None = None


class CommandsTable(Table):
    drive: DriveTable
    brake: BrakeTable
    steer: SteerTable

    @model_validator(mode="after")
    def _three_messages(self) -> CommandsTable:
        if len({self.drive.message, self.brake.message, self.steer.message}) != 3:
            raise ValueError("drive, brake and steer must be three different messages")
        return self


_ReportQuantities = create_model(
    "_ReportQuantities", __base__=Table,
    **{q: ((SignalRefText, ...) if q in REQUIRED_REPORTS else (SignalRefText | None, None)) for q in REPORT_QUANTITIES})


class ReportsTable(_ReportQuantities):  # type: ignore[misc, valid-type]
    """Which signal carries each reported quantity, the enable states, the e-stop values and fault signals."""

    enabled: list[SignalRefText] = Field(default_factory=list)
    estop_values: dict[Literal[ESTOP_SOURCES], int] = Field(default_factory=dict)  # type: ignore[valid-type]
    faults: dict[str, SignalRefText] = Field(default_factory=dict)

    @field_validator("estop_values")
    @classmethod
    def _none_value(cls, value: dict[str, int], info: ValidationInfo) -> dict[str, int]:
        if info.data.get("estop") is not None and "none" not in value:
            raise ValueError("needs 'none' (the value that means no e-stop)")
        return value

    def quantities(self) -> dict[str, str]:
        return {q: getattr(self, q) for q in REPORT_QUANTITIES if getattr(self, q) is not None}


class IntegrityEntry(Table):
    counter: str | None = None
    checksum: str | None = None


class SecuredEntry(Table):
    freshness: str
    mac: str


def _between(lo: int, hi: int) -> AfterValidator:
    def check(value: int) -> int:
        if not lo <= value <= hi:
            raise ValueError(f"must be {lo} to {hi}, got {value}")
        return value
    return AfterValidator(check)


class SecocTable(Table):
    mac_bits: Annotated[int, _between(*MAC_BITS)]
    freshness_bits: Annotated[int, _between(*FRESHNESS_BITS)]
    freshness_window: int
    key_env: str = Field(min_length=1)
    test_key: str | None = None
    messages: dict[str, SecuredEntry] = Field(min_length=1)

    @field_validator("freshness_window")
    @classmethod
    def _within_the_counter(cls, value: int, info: ValidationInfo) -> int:
        bits = info.data.get("freshness_bits", FRESHNESS_BITS[1])
        return _between(1, (1 << bits) - 1).func(value)


class SimulationTable(Table):
    step_request: str
    step_done: str
    truth_position: str | None = None
    truth_motion: str | None = None
    truth: bool = False

    @field_validator("truth")
    @classmethod
    def _truth_frames(cls, value: bool, info: ValidationInfo) -> bool:
        if value and not (info.data.get("truth_position") and info.data.get("truth_motion")):
            raise ValueError("needs truth_position and truth_motion")
        return value


def _requires(*names: str) -> Any:
    def check(value: dict[str, int]) -> dict[str, int]:
        missing = [n for n in names if n not in value]
        if missing:
            raise ValueError(f"needs {', '.join(missing)}")
        return value
    return check


class ProfileDocument(Table):
    """The whole profile.toml."""

    name: str | None = None
    description: str = ""
    dbc: str = "chassis.dbc"
    timing: TimingTable
    longitudinal: LongitudinalTable
    steering: SteeringTable
    commands: CommandsTable
    gears: dict[Literal[GEARS], int]  # type: ignore[valid-type]
    modes: dict[Literal[MODES], int]  # type: ignore[valid-type]
    reports: ReportsTable
    integrity: dict[str, IntegrityEntry] = Field(default_factory=dict)
    simulation: SimulationTable
    secoc: SecocTable | None = None

    _gears = field_validator("gears")(_requires("drive", "neutral"))
    _modes = field_validator("modes")(_requires("standby", "self_driving"))
