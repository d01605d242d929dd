"""Chassis profiles: a folder with `chassis.dbc` and `profile.toml` that says which signal carries each command
and report, the units and enums, life counters and checksums, cycle times, time-outs and limits.

`load_profile("pix-hooke")` finds a shipped profile under hil/profiles/; any other argument is a folder path (a
user's own chassis needs no code change). Every problem raises a one-line ProfileError naming the field.
Signals are written "Message.Signal"; values in profile.toml are SI units except where a key says otherwise
(`*_deg`, `*_ms`, percent on the wire). An optional [secoc] table authenticates messages (`hil.secoc`): their
freshness and MAC signals, the lengths, the freshness window and where the key comes from (`hil.secoc_key`).
"""

from __future__ import annotations

import functools
import math
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cantools
from cantools.database.can import Database
from cantools.database.can import Message as DbcMessage

from hil.secoc import key_from_hex
from testbed.errors import UserError

PROFILES_DIR = Path(__file__).resolve().parent / "profiles"
DEFAULT_PROFILE = "ld3-dev"
CHECKSUM_START_BIT, CHECKSUM_LENGTH = 56, 8
MAC_BITS, FRESHNESS_BITS = (16, 64), (2, 16)  # the lengths [secoc] accepts
REPORT_QUANTITIES = (
    "speed", "accel", "steer", "yaw_rate", "gear", "mode", "estop", "brake_pct", "throttle_pct",
    "emergency_active", "steer_limited", "comm_fault_level", "bad_checksum_count", "bad_counter_count",
    "bad_format_count", "bad_freshness_count", "bad_mac_count",
)
ESTOP_SOURCES = (
    "none", "command_timeout", "bad_frames", "foreign_node", "emergency_brake_command", "chassis_button",
)
GEARS = ("no_request", "park", "reverse", "neutral", "drive")
MODES = ("standby", "self_driving", "remote", "manual")


class ProfileError(UserError):
    """A chassis profile that cannot be used; the message names the profile and the field."""


@dataclass(frozen=True)
class SignalRef:
    """One signal of one DBC message."""

    message: str
    signal: str

    def __str__(self) -> str:
        return f"{self.message}.{self.signal}"


@dataclass(frozen=True)
class Timing:
    """Cycle of commands and reports, the chassis's own command time-out, the bridge's report time-out (s)."""

    cycle_s: float
    command_timeout_s: float
    report_timeout_s: float


@dataclass(frozen=True)
class Longitudinal:
    """Wire scaling (m/s² at 100 % throttle / brake) and the limits the bridge commands within (m/s²)."""

    full_throttle_accel: float
    full_brake_decel: float
    max_accel: float
    max_decel: float
    fault_decel: float


@dataclass(frozen=True)
class Steering:
    """Road-wheel angle <-> wire: wire degrees = sign * ratio * road-wheel degrees; limits are road wheel."""

    ratio: float
    sign: int
    max_angle: float
    max_rate: float

    def to_wire(self, road_wheel_rad: float) -> float:
        return self.sign * self.ratio * math.degrees(road_wheel_rad)

    def from_wire(self, wire_deg: float) -> float:
        return math.radians(wire_deg / (self.sign * self.ratio))


@dataclass(frozen=True)
class CommandLayout:
    """The three command messages and the signals the bridge fills; `constants` are fixed per message."""

    drive: str
    brake: str
    steer: str
    drive_enable: str
    gear: str
    throttle: str
    brake_enable: str
    pedal: str
    emergency: str | None
    steer_enable: str
    angle: str
    rate: str | None
    constants: dict[str, dict[str, float]]

    @property
    def messages(self) -> tuple[str, str, str]:
        return self.drive, self.brake, self.steer


@dataclass(frozen=True)
class ReportLayout:
    """Which signal carries each reported quantity, the enable-state signals, e-stop values and fault signals."""

    quantities: dict[str, SignalRef]
    enabled: tuple[SignalRef, ...]
    estop_values: dict[str, int]
    faults: dict[str, SignalRef]

    @property
    def messages(self) -> tuple[str, ...]:
        refs = [*self.quantities.values(), *self.enabled, *self.faults.values()]
        return tuple(dict.fromkeys(ref.message for ref in refs))


@dataclass(frozen=True)
class Integrity:
    """A message's 4-bit life counter and XOR checksum signals (None: the message carries none)."""

    counter: str | None = None
    checksum: str | None = None


@dataclass(frozen=True)
class SecuredSignals:
    """The signals of one message that carry its truncated freshness value and truncated MAC."""

    freshness: str
    mac: str


@dataclass(frozen=True)
class Secoc:
    """SecOC-style authentication (`hil.secoc`): the secured messages, field lengths in bits, the receiver's
    freshness window, the environment variable holding the key and an optional published test key."""

    mac_bits: int
    freshness_bits: int
    freshness_window: int
    key_env: str
    test_key: bytes | None
    messages: dict[str, SecuredSignals]


@dataclass(frozen=True)
class SimulationFrames:
    """Emulator-only frames: the lockstep clock and (optional, for measuring) the true pose."""

    step_request: str
    step_done: str
    truth_position: str | None
    truth_motion: str | None
    truth: bool


@dataclass(frozen=True)
class ChassisProfile:
    """A chassis protocol: its DBC and how the bridge and the ECU emulator use it."""

    name: str
    description: str
    root: Path
    dbc_path: Path
    db: Database
    timing: Timing
    longitudinal: Longitudinal
    steering: Steering
    commands: CommandLayout
    gears: dict[str, int]
    modes: dict[str, int]
    reports: ReportLayout
    integrity: dict[str, Integrity]
    simulation: SimulationFrames
    secoc: Secoc | None = None

    def message(self, name: str) -> DbcMessage:
        return self.db.get_message_by_name(name)

    def frame_id(self, name: str) -> int:
        return self.message(name).frame_id

    @property
    def command_ids(self) -> frozenset[int]:
        return frozenset(self.frame_id(name) for name in self.commands.messages)

    @property
    def report_ids(self) -> frozenset[int]:
        return frozenset(self.frame_id(name) for name in self.reports.messages)


class _Table:
    """A TOML table with the dotted path of its fields, for one-line errors."""

    def __init__(self, profile: str, path: str, data: Any) -> None:
        if not isinstance(data, dict):
            raise ProfileError(f"profile {profile}: {path}: expected a table")
        self.profile, self.path, self.data = profile, path, data
        self._used: set[str] = set()

    def error(self, key: str, problem: str) -> ProfileError:
        where = f"{self.path}.{key}" if self.path else key
        return ProfileError(f"profile {self.profile}: {where}: {problem}")

    def raw(self, key: str, default: Any = ...) -> Any:
        self._used.add(key)
        if key not in self.data:
            if default is ...:
                raise self.error(key, "missing")
            return default
        return self.data[key]

    def table(self, key: str, default: Any = ...) -> _Table:
        value = self.raw(key, {} if default is not ... else ...)
        return _Table(self.profile, f"{self.path}.{key}" if self.path else key, value)

    def text(self, key: str, default: Any = ...) -> Any:
        value = self.raw(key, default)
        if value is not None and not isinstance(value, str):
            raise self.error(key, f"expected a string, got {value!r}")
        return value

    def number(self, key: str, default: Any = ..., positive: bool = True) -> float:
        value = self.raw(key, default)
        if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
            raise self.error(key, f"expected a number, got {value!r}")
        if positive and value <= 0:
            raise self.error(key, f"must be > 0, got {value!r}")
        return float(value)

    def integer(self, key: str, lo: int, hi: int) -> int:
        value = self.raw(key)
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.error(key, f"expected an integer, got {value!r}")
        if not lo <= value <= hi:
            raise self.error(key, f"must be {lo} to {hi}, got {value}")
        return value

    def integers(self, names: tuple[str, ...] | None, required: tuple[str, ...]) -> dict[str, int]:
        out = {}
        for key, value in self.data.items():
            if names is not None and key not in names:
                raise self.error(key, f"unknown name; choose from {', '.join(names)}")
            if isinstance(value, bool) or not isinstance(value, int):
                raise self.error(key, f"expected an integer, got {value!r}")
            out[key] = value
        for key in required:
            if key not in out:
                raise self.error(key, "missing")
        return out

    def check_unknown(self) -> None:
        unknown = sorted(set(self.data) - self._used)
        if unknown:
            raise self.error(unknown[0], "unknown key")


class _Builder:
    """Parses and checks profile.toml against its DBC."""

    def __init__(self, name: str, root: Path, data: dict[str, Any]) -> None:
        self.name = name
        self.top = _Table(name, "", data)
        dbc_name = self.top.text("dbc", "chassis.dbc")
        self.dbc_path = root / dbc_name
        if not self.dbc_path.is_file():
            raise self.top.error("dbc", f"file not found: {self.dbc_path}")
        try:
            self.db = cantools.database.load_file(str(self.dbc_path), strict=True)
        except Exception as exc:  # cantools raises several parse error types
            raise ProfileError(f"profile {name}: dbc: cannot load {self.dbc_path.name}: {exc}") from None
        self.root = root

    def message(self, table: _Table, key: str, name: str) -> DbcMessage:
        try:
            message = self.db.get_message_by_name(name)
        except KeyError:
            raise table.error(key, f"no message {name!r} in {self.dbc_path.name}") from None
        if message.length != 8 or message.is_extended_frame:
            raise table.error(key, f"{name} must be a standard 8-byte frame")
        return message

    def signal(self, table: _Table, key: str, message: DbcMessage, name: str | None) -> str | None:
        if name is None:
            return None
        if name not in [s.name for s in message.signals]:
            raise table.error(key, f"message {message.name} has no signal {name!r}")
        return name

    def ref(self, table: _Table, key: str, text: Any) -> SignalRef:
        if not isinstance(text, str) or text.count(".") != 1:
            raise table.error(key, f"expected \"Message.Signal\", got {text!r}")
        message_name, signal_name = text.split(".")
        message = self.message(table, key, message_name)
        self.signal(table, key, message, signal_name)
        return SignalRef(message_name, signal_name)

    def build(self) -> ChassisProfile:
        top = self.top
        profile_name = top.text("name", self.name)
        description = top.text("description", "")
        timing = self.timing(top.table("timing"))
        longitudinal = self.longitudinal(top.table("longitudinal"))
        steering = self.steering(top.table("steering"))
        commands = self.commands(top.table("commands"))
        gears = top.table("gears").integers(GEARS, ("drive", "neutral"))
        modes = top.table("modes").integers(MODES, ("standby", "self_driving"))
        reports = self.reports(top.table("reports"))
        integrity = self.integrity(top.table("integrity", {}))
        simulation = self.simulation(top.table("simulation"))
        secoc = self.secoc(top.table("secoc"), integrity) if "secoc" in top.data else None
        top.check_unknown()
        return ChassisProfile(profile_name, description, self.root, self.dbc_path, self.db, timing, longitudinal,
                              steering, commands, gears, modes, reports, integrity, simulation, secoc)

    def timing(self, t: _Table) -> Timing:
        timing = Timing(t.number("cycle_ms") / 1e3, t.number("command_timeout_ms") / 1e3,
                        t.number("report_timeout_ms") / 1e3)
        if timing.command_timeout_s < timing.cycle_s:
            raise t.error("command_timeout_ms", "shorter than one cycle")
        t.check_unknown()
        return timing

    def longitudinal(self, t: _Table) -> Longitudinal:
        values = Longitudinal(*(t.number(k) for k in (
            "full_throttle_accel", "full_brake_decel", "max_accel", "max_decel", "fault_decel")))
        if values.max_accel > values.full_throttle_accel:
            raise t.error("max_accel", "exceeds full_throttle_accel")
        if values.max_decel > values.full_brake_decel:
            raise t.error("max_decel", "exceeds full_brake_decel")
        t.check_unknown()
        return values

    def steering(self, t: _Table) -> Steering:
        positive = t.text("positive", "left")
        if positive not in ("left", "right"):
            raise t.error("positive", f"expected \"left\" or \"right\", got {positive!r}")
        steering = Steering(t.number("ratio"), 1 if positive == "left" else -1,
                            math.radians(t.number("max_angle_deg")), math.radians(t.number("max_rate_deg_s")))
        t.check_unknown()
        return steering

    def commands(self, t: _Table) -> CommandLayout:
        parts = {}
        roles = {"drive": ("enable", "gear", "throttle"), "brake": ("enable", "pedal"), "steer": ("enable", "angle")}
        optional = {"drive": (), "brake": ("emergency",), "steer": ("rate",)}
        constants: dict[str, dict[str, float]] = {}
        for part in ("drive", "brake", "steer"):
            table = t.table(part)
            message = self.message(table, "message", table.text("message"))
            fields = {"message": message.name}
            for key in roles[part]:
                fields[key] = self.signal(table, key, message, table.text(key))
            for key in optional[part]:
                fields[key] = self.signal(table, key, message, table.text(key, None))
            fixed = table.table("constants", {})
            for signal_name in fixed.data:
                self.signal(fixed, signal_name, message, signal_name)
                fixed.number(signal_name, positive=False)
            constants[message.name] = {k: float(v) for k, v in fixed.data.items()}
            table.check_unknown()
            parts[part] = fields
        names = [parts[p]["message"] for p in parts]
        if len(set(names)) != 3:
            raise t.error("drive.message", "drive, brake and steer must be three different messages")
        t.check_unknown()
        d, b, s = parts["drive"], parts["brake"], parts["steer"]
        return CommandLayout(d["message"], b["message"], s["message"], d["enable"], d["gear"], d["throttle"],
                             b["enable"], b["pedal"], b["emergency"], s["enable"], s["angle"], s["rate"], constants)

    def reports(self, t: _Table) -> ReportLayout:
        quantities = {}
        for key in REPORT_QUANTITIES:
            text = t.raw(key, None)
            if text is not None:
                quantities[key] = self.ref(t, key, text)
        for key in ("speed", "steer", "mode"):
            if key not in quantities:
                raise t.error(key, "missing")
        enabled_list = t.raw("enabled", [])
        if not isinstance(enabled_list, list):
            raise t.error("enabled", "expected a list of \"Message.Signal\"")
        enabled = tuple(self.ref(t, "enabled", text) for text in enabled_list)
        estop_values = t.table("estop_values", {}).integers(ESTOP_SOURCES, ())
        if "estop" in quantities and "none" not in estop_values:
            raise t.error("estop_values.none", "missing (the value that means no e-stop)")
        fault_table = t.table("faults", {})
        faults = {key: self.ref(fault_table, key, text) for key, text in fault_table.data.items()}
        t.check_unknown()
        return ReportLayout(quantities, enabled, estop_values, faults)

    def integrity(self, t: _Table) -> dict[str, Integrity]:
        out = {}
        for message_name in t.data:
            entry = t.table(message_name)
            message = self.message(t, message_name, message_name)
            counter = self.signal(entry, "counter", message, entry.text("counter", None))
            checksum = self.signal(entry, "checksum", message, entry.text("checksum", None))
            if counter is not None and message.get_signal_by_name(counter).length != 4:
                raise entry.error("counter", "a life counter must be 4 bits")
            if checksum is not None:
                signal = message.get_signal_by_name(checksum)
                if (signal.start, signal.length) != (CHECKSUM_START_BIT, CHECKSUM_LENGTH):
                    raise entry.error("checksum", "the XOR checksum must be byte 7 (start bit 56, 8 bits)")
            entry.check_unknown()
            out[message_name] = Integrity(counter, checksum)
        return out

    def secoc(self, t: _Table, integrity: dict[str, Integrity]) -> Secoc:
        mac_bits = t.integer("mac_bits", MAC_BITS[0], MAC_BITS[1])
        freshness_bits = t.integer("freshness_bits", FRESHNESS_BITS[0], FRESHNESS_BITS[1])
        window = t.integer("freshness_window", 1, (1 << freshness_bits) - 1)
        key_env = t.text("key_env")
        if not key_env:
            raise t.error("key_env", "expected the name of an environment variable")
        test_key = t.text("test_key", None)
        if test_key is not None:
            try:
                test_key = key_from_hex(test_key)
            except ValueError as exc:
                raise t.error("test_key", str(exc)) from None
        table = t.table("messages")
        if not table.data:
            raise t.error("messages", "no secured message")
        messages = {}
        for message_name in table.data:
            entry = table.table(message_name)
            message = self.message(table, message_name, message_name)
            if message_name in integrity:
                raise table.error(message_name, "also in [integrity]: a secured message carries no life counter or "
                                                "checksum")
            fields = {}
            for key, bits in (("freshness", freshness_bits), ("mac", mac_bits)):
                name = self.signal(entry, key, message, entry.text(key))
                signal = message.get_signal_by_name(name)
                if signal.byte_order != "little_endian" or signal.is_signed or signal.length != bits:
                    raise entry.error(key, f"{name} must be an unsigned little-endian signal of {bits} bits")
                fields[key] = name
            entry.check_unknown()
            messages[message_name] = SecuredSignals(fields["freshness"], fields["mac"])
        t.check_unknown()
        return Secoc(mac_bits, freshness_bits, window, key_env, test_key, messages)

    def simulation(self, t: _Table) -> SimulationFrames:
        names = {}
        for key, required in (("step_request", True), ("step_done", True), ("truth_position", False),
                              ("truth_motion", False)):
            name = t.text(key) if required else t.text(key, None)
            if name is not None:
                self.message(t, key, name)
            names[key] = name
        truth = t.raw("truth", False)
        if not isinstance(truth, bool):
            raise t.error("truth", f"expected true or false, got {truth!r}")
        if truth and not (names["truth_position"] and names["truth_motion"]):
            raise t.error("truth", "needs truth_position and truth_motion")
        t.check_unknown()
        return SimulationFrames(names["step_request"], names["step_done"], names["truth_position"],
                                names["truth_motion"], truth)


def profile_dir(spec: str | Path) -> Path:
    """The folder of a profile given by shipped name or path."""
    shipped = PROFILES_DIR / str(spec)
    if isinstance(spec, str) and "/" not in spec and shipped.is_dir():
        return shipped
    return Path(spec)


@functools.lru_cache(maxsize=16)
def _load(root: Path) -> ChassisProfile:
    toml_path = root / "profile.toml"
    if not toml_path.is_file():
        shipped = ", ".join(sorted(p.name for p in PROFILES_DIR.iterdir() if p.is_dir()))
        raise ProfileError(f"no chassis profile at {root} (profile.toml missing); shipped profiles: {shipped}")
    try:
        data = tomllib.loads(toml_path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise ProfileError(f"profile {root.name}: profile.toml: {exc}") from None
    return _Builder(root.name, root, data).build()


def load_profile(spec: str | Path = DEFAULT_PROFILE) -> ChassisProfile:
    """The profile named `spec` (shipped) or found in folder `spec`; raises ProfileError."""
    return _load(profile_dir(spec).resolve())


def default_profile() -> ChassisProfile:
    return load_profile(DEFAULT_PROFILE)
