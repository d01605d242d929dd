"""The chassis DBC: loads in strict mode, dumps cleanly, and has the protocol's IDs, DLC and cycle times."""

import subprocess
import sys

import cantools

from hil.link.codec import DBC_PATH

COMMANDS = {0x130: "ACU_DriveCtrl", 0x131: "ACU_BrakeCtrl", 0x132: "ACU_SteerCtrl"}
REPORTS = {0x530, 0x531, 0x532, 0x534, 0x537}


def test_dbc_loads_strict_with_the_protocol_layout():
    db = cantools.database.load_file(str(DBC_PATH), strict=True)
    by_id = {m.frame_id: m for m in db.messages}
    assert {i: by_id[i].name for i in COMMANDS} == COMMANDS
    assert set(by_id) >= REPORTS
    for frame_id in (*COMMANDS, *REPORTS):
        message = by_id[frame_id]
        assert message.length == 8 and not message.is_extended_frame
        assert message.cycle_time == 20
        assert all(s.byte_order == "little_endian" for s in message.signals)
        checksum = [s for s in message.signals if s.name.endswith("Checksum")]
        assert len(checksum) == 1 and checksum[0].start == 56 and checksum[0].length == 8
    for frame_id in (*COMMANDS, 0x534):
        life = [s for s in by_id[frame_id].signals if s.name.endswith("Life")]
        assert len(life) == 1 and life[0].length == 4
    modes = by_id[0x534].get_signal_by_name("DrivingMode").choices
    assert {str(v) for v in modes.values()} == {"Standby", "SelfDriving", "Remote", "Manual"}


def test_cantools_dump_reads_cleanly():
    result = subprocess.run(
        [sys.executable, "-m", "cantools", "dump", str(DBC_PATH)], capture_output=True, text=True, timeout=60
    )
    assert result.returncode == 0, result.stderr
    assert result.stderr == ""
    assert "ACU_SteerCtrl" in result.stdout and "VCU_FaultStatus" in result.stdout
