"""Hypothesis fuzz, per shipped profile: >= 10,000 random, mutated and replayed frames into the ECU and into the
bridge.

No crash, and a frame is accepted exactly when an independent check of format, checksum (where the profile
declares one), freshness and MAC (where it secures the ID; the MAC recomputed with the RFC 4493 reference),
range and life counter passes; the ranges are read straight from the bytes below.
"""

import uuid
from collections.abc import Callable
from typing import NamedTuple

import can
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hil.emulator.ecu import EcuEmulator
from hil.emulator.kinematic_plant import KinematicBicyclePlant
from hil.link.actuator_map import ActuatorRequest, Gear
from hil.link.bridge import CanChassisBridge
from hil.link.codec import ChassisCodec
from hil.link.profile import load_profile
from hil.link.report_map import DrivingMode, EStopSource, VcuReport
from testbed.chassis import ChassisCommand
from tests.hil.link.cmac_reference import RFC4493_KEY, cmac
from tracks.pose import Pose

FRAMES_PER_EXAMPLE = 420
EXAMPLES = 25
COMMAND_IDS = (0x130, 0x131, 0x132)
STEP_REQUEST_ID = 0x5F0
TEMPLATE_CYCLES = 3  # consecutive frames per ID among the templates (successive counters and freshness values)
SECOC_WINDOW = 8


def _xor(data: bytes) -> int:
    value = 0
    for byte in data[:7]:
        value ^= byte
    return value


def _u16(data: bytes, i: int) -> int:
    return int.from_bytes(data[i : i + 2], "little")


def _s16(data: bytes, i: int) -> int:
    return int.from_bytes(data[i : i + 2], "little", signed=True)


def _u10(data: bytes, i: int) -> int:
    return data[i] | (data[i + 1] & 0x03) << 8


def ld3_dev_in_range(frame_id: int, data: bytes) -> bool:
    u16 = _u16(data, 2)
    if frame_id == 0x130:
        return data[1] & 0x0F <= 4 and u16 <= 10000
    if frame_id == 0x131:
        return u16 <= 10000
    if frame_id == 0x132:
        return _u16(data, 3) <= 60000
    if frame_id == 0x530:
        return data[1] & 0x0F <= 4
    if frame_id == 0x531:
        return u16 <= 10000
    if frame_id == 0x534:
        return data[1] & 0x0F <= 5
    if frame_id == 0x537:
        return all(level <= 3 for level in (data[0] & 0x0F, data[0] >> 4, data[1] & 0x0F, data[1] >> 4))
    return True


def pix_hooke_in_range(frame_id: int, data: bytes) -> bool:
    steer_ok = abs(_s16(data, 1)) <= 500 and abs(_s16(data, 3)) <= 500 and data[5] <= 250
    if frame_id == 0x130:
        return _u16(data, 1) <= 5000 and _u10(data, 3) <= 1000
    if frame_id == 0x131:
        return _u10(data, 1) <= 1000
    if frame_id in (0x132, 0x532):
        return steer_ok
    if frame_id == 0x530:
        return abs(_s16(data, 1)) <= 5000 and _u10(data, 3) <= 1000 and abs(_s16(data, 5)) <= 2000
    if frame_id == 0x531:
        return _u10(data, 1) <= 1000
    if frame_id == 0x534:
        return _u16(data, 2) <= 500 and data[4] <= 250
    return True  # 0x537: every 4-bit level is in the public range 0-15


def ld3_dev_secoc_in_range(frame_id: int, data: bytes) -> bool:
    if frame_id in (0x130, 0x530):
        return data[1] & 0x0F <= 4 and (frame_id == 0x530 or _u16(data, 2) <= 10000)
    if frame_id in (0x131, 0x531):
        return _u16(data, 2) <= 10000
    if frame_id == 0x132:
        return _u16(data, 0) >> 1 <= 30000
    if frame_id == 0x534:
        return data[1] & 0x0F <= 5
    if frame_id == 0x537:
        return all(level <= 3 for level in (data[0] & 0x0F, data[0] >> 4, data[1] & 0x0F, data[1] >> 4))
    return True


class FuzzSpec(NamedTuple):
    """What the oracle checks for one profile."""

    report_ids: tuple[int, ...]
    life_ids: tuple[int, ...]  # command and report IDs with a life counter
    checksum_ids: tuple[int, ...] | None  # IDs carrying the XOR checksum (None: all)
    in_range: Callable[[int, bytes], bool]
    secured_ids: tuple[int, ...] = ()  # SecOC: freshness in byte 4, 24-bit MAC in bytes 5-7 (RFC 4493 test key)


SECOC_REPORT_IDS = (0x530, 0x531, 0x532, 0x533, 0x534, 0x537, 0x538)
PROFILES = {
    "ld3-dev": FuzzSpec(
        (0x530, 0x531, 0x532, 0x534, 0x537, 0x540, 0x541, 0x5F1), (*COMMAND_IDS, 0x534), None, ld3_dev_in_range
    ),
    "ld3-dev-secoc": FuzzSpec(
        (*SECOC_REPORT_IDS, 0x540, 0x541, 0x5F1),
        (),
        (0x540, 0x541, 0x5F0, 0x5F1),
        ld3_dev_secoc_in_range,
        (*COMMAND_IDS, *SECOC_REPORT_IDS),
    ),
    "pix-hooke": FuzzSpec(
        (0x530, 0x531, 0x532, 0x534, 0x537, 0x5F1, 0x5F2, 0x5F3),
        (0x130, 0x131, 0x534),
        (*COMMAND_IDS, 0x534, 0x5F0, 0x5F1, 0x5F2, 0x5F3),
        pix_hooke_in_range,
    ),
}


def frames(ids: tuple[int, ...], templates: list[tuple[int, bytes]]) -> st.SearchStrategy[can.Message]:
    """Random frames, valid templates with one byte mutated and the checksum recomputed (or not), and valid
    templates replayed verbatim (in any order, so mostly stale)."""
    random_frame = st.builds(
        lambda i, ext, rem, data: can.Message(
            arbitration_id=i,
            is_extended_id=ext,
            is_remote_frame=rem,
            dlc=len(data),
            data=b"" if rem else data,
        ),
        st.one_of(st.sampled_from(ids), st.integers(0, 0x7FF)),
        st.booleans() | st.just(False),
        st.just(False) | st.booleans(),
        st.binary(min_size=0, max_size=8),
    )

    def mutate(template: tuple[int, bytes], index: int, value: int, reseal: bool, life: int) -> can.Message:
        frame_id, data = template
        payload = bytearray(data)
        payload[index] = value
        payload[6] = (payload[6] & 0xF0) | life
        if reseal:
            payload[7] = _xor(payload)
        return can.Message(arbitration_id=frame_id, is_extended_id=False, data=payload)

    mutated = st.builds(
        mutate,
        st.sampled_from(templates),
        st.integers(0, 6),
        st.integers(0, 255),
        st.booleans(),
        st.integers(0, 15),
    )
    verbatim = st.sampled_from(templates).map(
        lambda t: can.Message(arbitration_id=t[0], is_extended_id=False, data=t[1])
    )
    return st.one_of(random_frame, mutated, mutated, verbatim)


def profile_key(profile) -> bytes | None:
    """The published test key of a secured profile (the oracle's RFC 4493 key), else None."""
    if profile.secoc is None:
        return None
    assert profile.secoc.test_key == RFC4493_KEY
    return profile.secoc.test_key


def command_templates(profile) -> list[tuple[int, bytes]]:
    codec = ChassisCodec(profile, profile_key(profile))
    request = ActuatorRequest.from_command(ChassisCommand(0.1, 1.0), enable=True, steer_rate=0.5)
    signals = request.to_signals(profile)
    encoded = [codec.encode(n, s) for _ in range(TEMPLATE_CYCLES) for n, s in signals.items()]
    return [(f.arbitration_id, bytes(f.data)) for f in encoded]


def report_templates(profile) -> list[tuple[int, bytes]]:
    codec = ChassisCodec(profile, profile_key(profile))
    report = VcuReport(
        1.0, 0.1, 0.05, Gear.DRIVE, True, 0.0, False, False, DrivingMode.SELF_DRIVING, EStopSource.NONE,
        False, False, False, 0, 0, 0, Pose(10.0, -3.0, 0.4), 0.0,
    )
    signals = report.to_signals(profile, truth=True)
    return [(codec.frame_id(n), bytes(codec.encode(n, s).data)) for _ in range(TEMPLATE_CYCLES)
            for n, s in signals.items()]


class Oracle:
    """Independent verdict per frame of the IDs in `known_ids`, tracking life counters and freshness values."""

    def __init__(self, known_ids: tuple[int, ...], spec: FuzzSpec) -> None:
        self.known = known_ids
        self.life_ids = spec.life_ids
        self.checksum_ids = spec.checksum_ids
        self.in_range = spec.in_range
        self.secured_ids = spec.secured_ids
        self.last: dict[int, int] = {}
        self.freshness: dict[int, int] = {}

    def authentic(self, frame_id: int, data: bytes) -> bool:
        """Freshness within the window above the last accepted value, then the MAC; only then the value moves."""
        last = self.freshness.get(frame_id, 0)
        value = last - last % 256 + data[4]
        if value <= last:
            value += 256
        if value - last > SECOC_WINDOW:
            return False
        tag = cmac(RFC4493_KEY, frame_id.to_bytes(2, "big") + data[:4] + bytes(4) + value.to_bytes(8, "big"))
        if int.from_bytes(data[5:8], "little") != int.from_bytes(tag[:3], "big"):
            return False
        self.freshness[frame_id] = value
        return True

    def valid(self, frame: can.Message) -> bool:
        data = bytes(frame.data)
        frame_id = frame.arbitration_id
        if frame_id not in self.known or frame.is_extended_id or frame.is_remote_frame:
            return False
        if frame.dlc != 8 or len(data) != 8:
            return False
        if (self.checksum_ids is None or frame_id in self.checksum_ids) and data[7] != _xor(data):
            return False
        if frame_id in self.secured_ids and not self.authentic(frame_id, data):
            return False
        if not self.in_range(frame_id, data):
            return False
        if frame_id not in self.life_ids:
            return True
        life, last = data[6] & 0x0F, self.last.get(frame_id)
        self.last[frame_id] = life
        return last is None or life == (last + 1) % 16


@pytest.mark.parametrize("name", sorted(PROFILES))
def test_fuzz_ecu_accepts_exactly_the_valid_command_frames(name):
    profile = load_profile(name)
    spec = PROFILES[name]
    seen, accepted = [], []

    @settings(max_examples=EXAMPLES, deadline=None, suppress_health_check=list(HealthCheck), database=None)
    @given(
        st.lists(
            frames((*COMMAND_IDS, STEP_REQUEST_ID), command_templates(profile)),
            min_size=FRAMES_PER_EXAMPLE,
            max_size=FRAMES_PER_EXAMPLE,
        )
    )
    def check(batch):
        bus = can.Bus(interface="virtual", channel=f"fuzz-ecu-{uuid.uuid4().hex}")
        ecu = EcuEmulator(bus, KinematicBicyclePlant(), profile=profile, key=profile_key(profile))
        oracle = Oracle(COMMAND_IDS, spec)
        try:
            for frame in batch:
                before = ecu.guard.admitted
                ecu.handle(frame)
                expected = frame.arbitration_id in COMMAND_IDS and oracle.valid(frame)
                assert (ecu.guard.admitted - before == 1) == expected, frame
                accepted.append(expected)
            ecu.step(0.01)
        finally:
            bus.shutdown()
        seen.append(len(batch))

    check()
    assert sum(seen) >= 10_000
    assert any(accepted)  # valid frames were among them: both verdicts were exercised


@pytest.mark.parametrize("name", sorted(PROFILES))
def test_fuzz_bridge_accepts_exactly_the_valid_report_frames(name):
    profile = load_profile(name)
    spec = PROFILES[name]
    seen, accepted = [], []
    bus = can.Bus(interface="virtual", channel=f"fuzz-bridge-{uuid.uuid4().hex}")
    try:

        @settings(
            max_examples=EXAMPLES, deadline=None, suppress_health_check=list(HealthCheck), database=None
        )
        @given(
            st.lists(
                frames((*spec.report_ids, *COMMAND_IDS), report_templates(profile)),
                min_size=FRAMES_PER_EXAMPLE,
                max_size=FRAMES_PER_EXAMPLE,
            )
        )
        def check(batch):
            bridge = CanChassisBridge(bus, profile=profile, key=profile_key(profile))
            bridge.close()  # frames are fed by hand below
            oracle = Oracle(spec.report_ids, spec)
            for frame in batch:
                before = bridge.frames_accepted
                bridge.handle(frame)
                expected = oracle.valid(frame)
                assert (bridge.frames_accepted - before == 1) == expected, frame
                accepted.append(expected)
                bridge.read()
            seen.append(len(batch))

        check()
    finally:
        bus.shutdown()
    assert sum(seen) >= 10_000
    assert any(accepted)  # valid frames were among them: both verdicts were exercised


def test_a_dbc_message_the_profile_does_not_follow_is_not_read():
    """PIX's DBC holds the reserved tyre-pressure report (0x540); a well-formed frame of it is not a report."""
    profile = load_profile("pix-hooke")
    bus = can.Bus(interface="virtual", channel=f"unfollowed-{uuid.uuid4().hex}")
    try:
        bridge = CanChassisBridge(bus, profile=profile, key=profile_key(profile))
        bridge.close()
        frame = can.Message(arbitration_id=0x540, is_extended_id=False, data=bytes(8))
        assert bridge.codec.knows(0x540) and 0x540 not in profile.report_ids
        bridge.handle(frame)
        assert bridge.frames_accepted == 0 and not bridge.latched_faults()
    finally:
        bus.shutdown()
