"""Chassis profiles: a folder with `chassis.dbc` and `profile.toml` that says which signal carries each command
and report, the units and enums, life counters and checksums, cycle times, time-outs and limits.

`load_profile("pix-hooke")` finds a shipped profile under hil/link/profiles/; any other argument is a folder path (a
user's own chassis needs no code change). Every problem raises a one-line ProfileError naming the field.
Signals are written "Message.Signal"; values in profile.toml are SI units except where a key says otherwise
(`*_deg`, `*_ms`, percent on the wire). An optional [secoc] table authenticates messages (`hil.link.secoc`): their
freshness and MAC signals, the lengths, the freshness window and where the key comes from (`hil.link.secoc_key`).
"""

from __future__ import annotations

import functools
import logging
import math
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cantools
from cantools.database.can import Database
from cantools.database.can import Message as DbcMessage
from pydantic import ValidationError

from hil.link.profile_document import ProfileDocument
from hil.link.secoc import key_from_hex
from testbed.errors import UserError
from testbed.params import error_key, error_problem

PROFILES_DIR = Path(__file__).resolve().parent / "profiles"
DEFAULT_PROFILE = "ld3-dev"
CHECKSUM_START_BIT, CHECKSUM_LENGTH = 56, 8


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
    """SecOC-style authentication (`hil.link.secoc`): the secured messages, field lengths in bits, the receiver's
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
    report_cycles: dict[str, float] = field(default_factory=dict)

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

    def report_cycle_s(self, name: str) -> float:
        """How often report message `name` goes out (s): its DBC GenMsgCycleTime, else the profile's cycle."""
        return self.report_cycles.get(name, self.timing.cycle_s)

    def report_cycles_by_id(self) -> dict[int, float]:
        return {self.frame_id(name): self.report_cycle_s(name) for name in self.reports.messages}


MAX_CAN_BYTES = 8
MAX_FD_BYTES = 64
"""The most data bytes a classic CAN frame and a CAN FD frame carry."""
DBC_MESSAGE = re.compile(r"^BO_\s+\d+\s+(\w+)\s*:\s*(\d+)", re.MULTILINE)
"""A DBC message line: its name and its length in bytes."""


class _Builder:
    """Checks a validated profile.toml against its DBC and builds the profile."""

    def __init__(self, name: str, root: Path, doc: ProfileDocument) -> None:
        self.name, self.root, self.doc = name, root, doc
        self.dbc_path = root / doc.dbc
        if not self.dbc_path.is_file():
            raise self.error("dbc", f"file not found: {self.dbc_path}")
        self.check_lengths()
        log = logging.getLogger("cantools")  # its warnings (a repeated frame id) are refused below, in one line
        level = log.level
        log.setLevel(logging.ERROR)
        try:
            self.db = cantools.database.load_file(str(self.dbc_path), strict=True)
        except Exception as exc:  # cantools raises several parse error types
            raise self.error("dbc", f"cannot load {self.dbc_path.name}: {exc}") from None
        finally:
            log.setLevel(level)
        self.check_dbc()

    def check_lengths(self) -> None:
        """Refuse a message longer than a CAN FD frame before cantools reads the file: its strict check of the
        signals against the length takes minutes for a length of 99999 bytes."""
        try:
            text = self.dbc_path.read_bytes().decode("latin-1")
        except OSError as exc:
            raise self.error("dbc", f"cannot read {self.dbc_path.name}: {exc.strerror}") from None
        for match in DBC_MESSAGE.finditer(text):
            if int(match.group(2)) > MAX_FD_BYTES:
                raise self.error("dbc", f"message {match.group(1)} is {match.group(2)} bytes long; a CAN FD frame "
                                 f"carries at most {MAX_FD_BYTES}")

    def check_dbc(self) -> None:
        """Refuse a DBC whose frame ids repeat, whose frames are longer than a CAN frame carries (8 bytes, 64 for
        CAN FD: a longer one made every encode of the emulator's frames crawl), or whose signals have a zero scale
        (no value could be decoded)."""
        seen: dict[int, str] = {}
        for message in self.db.messages:
            most = MAX_FD_BYTES if message.is_fd else MAX_CAN_BYTES
            if not 0 <= message.length <= most:
                raise self.error("dbc", f"message {message.name} is {message.length} bytes long; a "
                                 f"{'CAN FD' if message.is_fd else 'CAN'} frame carries at most {most}")
            if message.frame_id in seen:
                raise self.error("dbc", f"frame id {message.frame_id} (0x{message.frame_id:X}) is used by both "
                                 f"{seen[message.frame_id]} and {message.name} in {self.dbc_path.name}")
            seen[message.frame_id] = message.name
            for signal in message.signals:
                if not (math.isfinite(signal.scale) and signal.scale != 0 and math.isfinite(signal.offset)):
                    raise self.error("dbc", f"signal {message.name}.{signal.name} has scale {signal.scale:g} "
                                     f"and offset {signal.offset:g}; the scale must be a finite number other than 0")

    def check_enum(self, where: str, message_name: str, signal_name: str, values: dict[str, int]) -> None:
        """Refuse enum values (gears, modes) the signal cannot carry: outside its DBC range or its bits."""
        signal = self.db.get_message_by_name(message_name).get_signal_by_name(signal_name)
        low = signal.minimum if signal.minimum is not None else signal.conversion.raw_to_scaled(
            -(1 << (signal.length - 1)) if signal.is_signed else 0, decode_choices=False)
        high = signal.maximum if signal.maximum is not None else signal.conversion.raw_to_scaled(
            (1 << (signal.length - 1)) - 1 if signal.is_signed else (1 << signal.length) - 1, decode_choices=False)
        for key, value in values.items():
            if not low <= value <= high:
                raise self.error(f"{where}.{key}", f"{value} does not fit signal {message_name}.{signal_name} "
                                 f"({low:g} to {high:g})")

    def error(self, where: str, problem: str) -> ProfileError:
        return ProfileError(f"profile {self.name}: {where}: {problem}")

    def message(self, where: str, name: str) -> DbcMessage:
        try:
            message = self.db.get_message_by_name(name)
        except KeyError:
            raise self.error(where, f"no message {name!r} in {self.dbc_path.name}") from None
        if message.length != 8 or message.is_extended_frame:
            raise self.error(where, f"{name} must be a standard 8-byte frame")
        return message

    def signal(self, where: str, message: DbcMessage, name: str | None) -> str | None:
        if name is not None and name not in [s.name for s in message.signals]:
            raise self.error(where, f"message {message.name} has no signal {name!r}")
        return name

    def ref(self, where: str, text: str) -> SignalRef:
        message_name, signal_name = text.split(".")
        self.signal(where, self.message(where, message_name), signal_name)
        return SignalRef(message_name, signal_name)

    def build(self) -> ChassisProfile:
        doc = self.doc
        t, lon, st = doc.timing, doc.longitudinal, doc.steering
        timing = Timing(t.cycle_ms / 1e3, t.command_timeout_ms / 1e3, t.report_timeout_ms / 1e3)
        longitudinal = Longitudinal(lon.full_throttle_accel, lon.full_brake_decel, lon.max_accel, lon.max_decel,
                                    lon.fault_decel)
        steering = Steering(st.ratio, 1 if st.positive == "left" else -1, math.radians(st.max_angle_deg),
                            math.radians(st.max_rate_deg_s))
        integrity = self.integrity()
        reports = self.reports()
        commands = self.commands()
        self.check_enum("gears", commands.drive, commands.gear, dict(doc.gears))
        for key, table in (("gear", doc.gears), ("mode", doc.modes)):
            if key in reports.quantities:
                ref = reports.quantities[key]
                self.check_enum(f"{key}s", ref.message, ref.signal, dict(table))
        return ChassisProfile(doc.name or self.name, doc.description, self.root, self.dbc_path, self.db, timing,
                              longitudinal, steering, commands, dict(doc.gears), dict(doc.modes),
                              reports, integrity, self.simulation(),
                              self.secoc(integrity) if doc.secoc is not None else None,
                              self.report_cycles(reports, timing))

    def report_cycles(self, reports: ReportLayout, timing: Timing) -> dict[str, float]:
        """Each report message's DBC cycle time (s), rounded up to whole command cycles (the emulator steps at the
        command cycle); the speed report must come more often than the report time-out."""
        cycles = {}
        for name in reports.messages:
            ms = self.db.get_message_by_name(name).cycle_time
            if ms is not None and ms > 0:
                cycles[name] = max(math.ceil(ms / 1e3 / timing.cycle_s - 1e-9), 1) * timing.cycle_s
        speed = cycles.get(reports.quantities["speed"].message, timing.cycle_s)
        if speed >= timing.report_timeout_s:
            raise self.error("timing.report_timeout_ms", f"not longer than the cycle of the speed report "
                             f"({speed * 1e3:.0f} ms)")
        return cycles

    def commands(self) -> CommandLayout:
        c = self.doc.commands
        signals: dict[str, str | None] = {}
        constants: dict[str, dict[str, float]] = {}
        for part, table in (("drive", c.drive), ("brake", c.brake), ("steer", c.steer)):
            message = self.message(f"commands.{part}.message", table.message)
            for key, name in table.model_dump(exclude={"message", "constants"}).items():
                signals[f"{part}.{key}"] = self.signal(f"commands.{part}.{key}", message, name)
            for name in table.constants:
                self.signal(f"commands.{part}.constants.{name}", message, name)
            constants[message.name] = dict(table.constants)
        return CommandLayout(c.drive.message, c.brake.message, c.steer.message, c.drive.enable, c.drive.gear,
                             c.drive.throttle, c.brake.enable, c.brake.pedal, c.brake.emergency, c.steer.enable,
                             c.steer.angle, c.steer.rate, constants)

    def reports(self) -> ReportLayout:
        r = self.doc.reports
        quantities = {key: self.ref(f"reports.{key}", text) for key, text in r.quantities().items()}
        enabled = tuple(self.ref("reports.enabled", text) for text in r.enabled)
        faults = {key: self.ref(f"reports.faults.{key}", text) for key, text in r.faults.items()}
        return ReportLayout(quantities, enabled, dict(r.estop_values), faults)

    def integrity(self) -> dict[str, Integrity]:
        out = {}
        for message_name, entry in self.doc.integrity.items():
            where = f"integrity.{message_name}"
            message = self.message(where, message_name)
            counter = self.signal(f"{where}.counter", message, entry.counter)
            checksum = self.signal(f"{where}.checksum", message, entry.checksum)
            if counter is not None and message.get_signal_by_name(counter).length != 4:
                raise self.error(f"{where}.counter", "a life counter must be 4 bits")
            if checksum is not None:
                signal = message.get_signal_by_name(checksum)
                if (signal.start, signal.length) != (CHECKSUM_START_BIT, CHECKSUM_LENGTH):
                    raise self.error(f"{where}.checksum", "the XOR checksum must be byte 7 (start bit 56, 8 bits)")
            out[message_name] = Integrity(counter, checksum)
        return out

    def secoc(self, integrity: dict[str, Integrity]) -> Secoc:
        sec = self.doc.secoc
        assert sec is not None
        test_key = None
        if sec.test_key is not None:
            try:
                test_key = key_from_hex(sec.test_key)
            except ValueError as exc:
                raise self.error("secoc.test_key", str(exc)) from None
        messages = {}
        for message_name, entry in sec.messages.items():
            where = f"secoc.messages.{message_name}"
            message = self.message(where, message_name)
            if message_name in integrity:
                raise self.error(where, "also in [integrity]: a secured message carries no life counter or checksum")
            for key, bits in (("freshness", sec.freshness_bits), ("mac", sec.mac_bits)):
                name = getattr(entry, key)
                self.signal(f"{where}.{key}", message, name)
                signal = message.get_signal_by_name(name)
                if signal.byte_order != "little_endian" or signal.is_signed or signal.length != bits:
                    raise self.error(f"{where}.{key}",
                                     f"{name} must be an unsigned little-endian signal of {bits} bits")
            messages[message_name] = SecuredSignals(entry.freshness, entry.mac)
        return Secoc(sec.mac_bits, sec.freshness_bits, sec.freshness_window, sec.key_env, test_key, messages)

    def simulation(self) -> SimulationFrames:
        sim = self.doc.simulation
        for key in ("step_request", "step_done", "truth_position", "truth_motion"):
            if getattr(sim, key) is not None:
                self.message(f"simulation.{key}", getattr(sim, key))
        return SimulationFrames(sim.step_request, sim.step_done, sim.truth_position, sim.truth_motion, sim.truth)


def _document(name: str, data: dict[str, Any]) -> ProfileDocument:
    """profile.toml validated, or a one-line ProfileError naming the first bad field."""
    try:
        return ProfileDocument.model_validate(data)
    except ValidationError as exc:
        err = exc.errors()[0]
        problem = error_problem(err)
        if "[key]" in err["loc"] and err["type"] == "literal_error":
            problem = f"unknown name; choose from {err['ctx']['expected']}"
        raise ProfileError(f"profile {name}: {error_key(err) or 'profile.toml'}: {problem}") from None


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
        data = tomllib.loads(toml_path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ProfileError(f"profile {root.name}: profile.toml: {exc}") from None
    except RecursionError:
        raise ProfileError(f"profile {root.name}: profile.toml: arrays or tables nested too deep") from None
    return _Builder(root.name, root, _document(root.name, data)).build()


def load_profile(spec: str | Path = DEFAULT_PROFILE) -> ChassisProfile:
    """The profile named `spec` (shipped) or found in folder `spec`; raises ProfileError."""
    try:
        root = profile_dir(spec).resolve()
    except (OSError, RuntimeError) as exc:  # RuntimeError: a symlink loop
        raise ProfileError(f"profile {spec}: cannot open the folder: {exc}") from None
    return _load(root)


def default_profile() -> ChassisProfile:
    return load_profile(DEFAULT_PROFILE)
