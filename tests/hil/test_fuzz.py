"""Hypothesis fuzz: >= 10,000 random and mutated frames into the ECU and into the bridge.

No crash, and a frame is accepted exactly when an independent check of format, checksum, range and life
counter passes.
"""

import uuid

import can
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hil.actuator_map import ActuatorRequest, Gear
from hil.bridge import CanChassisBridge
from hil.codec import ChassisCodec
from hil.ecu import EcuEmulator
from hil.kinematic_plant import KinematicBicyclePlant
from hil.report_map import DrivingMode, EStopSource, VcuReport
from testbed.chassis import ChassisCommand

FRAMES_PER_EXAMPLE = 420
EXAMPLES = 25
COMMAND_IDS = (0x130, 0x131, 0x132)
REPORT_IDS = (0x530, 0x531, 0x532, 0x534, 0x537, 0x540, 0x541, 0x5F1)


def _xor(data: bytes) -> int:
    value = 0
    for byte in data[:7]:
        value ^= byte
    return value


def frames(ids: tuple[int, ...], templates: list[bytes]) -> st.SearchStrategy[can.Message]:
    """Random frames, plus valid templates with one byte mutated and the checksum recomputed (or not)."""
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
    return st.one_of(random_frame, mutated, mutated)


def command_templates() -> list[tuple[int, bytes]]:
    codec = ChassisCodec()
    request = ActuatorRequest.from_command(ChassisCommand(0.1, 1.0), enable=True, steer_rate=1.0)
    encoded = [codec.encode(n, s) for n, s in request.to_signals().items()]
    return [(f.arbitration_id, bytes(f.data)) for f in encoded]


def report_templates() -> list[tuple[int, bytes]]:
    codec = ChassisCodec()
    report = VcuReport(
        1.0,
        0.1,
        0.05,
        Gear.DRIVE,
        True,
        0.0,
        False,
        False,
        DrivingMode.SELF_DRIVING,
        EStopSource.NONE,
        False,
        False,
        False,
        0,
        0,
        0,
        None,
        0.0,
    )
    return [(codec.frame_id(n), bytes(codec.encode(n, s).data)) for n, s in report.to_signals().items()]


def in_range(frame_id: int, data: bytes) -> bool:
    """The DBC ranges that raw values can exceed, read straight from the bytes."""
    u16 = int.from_bytes(data[2:4], "little")
    if frame_id == 0x130:
        return data[1] & 0x0F <= 4 and u16 <= 10000
    if frame_id == 0x131:
        return u16 <= 10000
    if frame_id == 0x132:
        return int.from_bytes(data[3:5], "little") <= 60000
    if frame_id == 0x530:
        return data[1] & 0x0F <= 4
    if frame_id == 0x531:
        return u16 <= 10000
    if frame_id == 0x534:
        return data[1] & 0x0F <= 4
    if frame_id == 0x537:
        return all(level <= 3 for level in (data[0] & 0x0F, data[0] >> 4, data[1] & 0x0F, data[1] >> 4))
    return True


class Oracle:
    """Independent verdict per frame, tracking the life counters of the IDs in `life_ids`."""

    def __init__(self, known_ids: tuple[int, ...], life_ids: tuple[int, ...]) -> None:
        self.known = known_ids
        self.life_ids = life_ids
        self.last: dict[int, int] = {}

    def valid(self, frame: can.Message) -> bool:
        data = bytes(frame.data)
        if frame.arbitration_id not in self.known or frame.is_extended_id or frame.is_remote_frame:
            return False
        if frame.dlc != 8 or len(data) != 8 or data[7] != _xor(data):
            return False
        if not in_range(frame.arbitration_id, data):
            return False
        if frame.arbitration_id not in self.life_ids:
            return True
        life, last = data[6] & 0x0F, self.last.get(frame.arbitration_id)
        self.last[frame.arbitration_id] = life
        return last is None or life == (last + 1) % 16


def test_fuzz_ecu_accepts_exactly_the_valid_command_frames():
    seen = []

    @settings(max_examples=EXAMPLES, deadline=None, suppress_health_check=list(HealthCheck), database=None)
    @given(
        st.lists(
            frames((*COMMAND_IDS, 0x5F0), command_templates()),
            min_size=FRAMES_PER_EXAMPLE,
            max_size=FRAMES_PER_EXAMPLE,
        )
    )
    def check(batch):
        bus = can.Bus(interface="virtual", channel=f"fuzz-ecu-{uuid.uuid4().hex}")
        ecu = EcuEmulator(bus, KinematicBicyclePlant())
        oracle = Oracle(COMMAND_IDS, COMMAND_IDS)
        try:
            for frame in batch:
                before = ecu.guard.admitted
                ecu.handle(frame)
                expected = frame.arbitration_id in COMMAND_IDS and oracle.valid(frame)
                assert (ecu.guard.admitted - before == 1) == expected, frame
            ecu.step(0.01)
        finally:
            bus.shutdown()
        seen.append(len(batch))

    check()
    assert sum(seen) >= 10_000


def test_fuzz_bridge_accepts_exactly_the_valid_report_frames():
    seen = []
    bus = can.Bus(interface="virtual", channel=f"fuzz-bridge-{uuid.uuid4().hex}")
    try:

        @settings(
            max_examples=EXAMPLES, deadline=None, suppress_health_check=list(HealthCheck), database=None
        )
        @given(
            st.lists(
                frames((*REPORT_IDS, *COMMAND_IDS), report_templates()),
                min_size=FRAMES_PER_EXAMPLE,
                max_size=FRAMES_PER_EXAMPLE,
            )
        )
        def check(batch):
            bridge = CanChassisBridge(bus)
            bridge.close()  # frames are fed by hand below
            oracle = Oracle(REPORT_IDS, (0x534,))
            for frame in batch:
                before = bridge.frames_accepted
                bridge.handle(frame)
                assert (bridge.frames_accepted - before == 1) == oracle.valid(frame), frame
                bridge.read()
            seen.append(len(batch))

        check()
    finally:
        bus.shutdown()
    assert sum(seen) >= 10_000
