"""The counter-copying injector (hil.emulator.injection_study): every forged steer frame passes ld3-dev's life counter
and checksum and pushes the car sideways; under ld3-dev-secoc every one is rejected and the car holds its lane."""

import math
import shutil

import pytest

from hil.emulator.counter_injector import CounterCopyingInjector
from hil.emulator.injection_study import main, measure_injection
from hil.link.codec import ChassisCodec, FrameRejected
from hil.link.profile import PROFILES_DIR, load_profile


def test_forged_frames_carry_the_successor_counter_and_the_offset():
    profile = load_profile("ld3-dev")
    tx, rx = ChassisCodec(profile), ChassisCodec(profile)
    genuine = tx.encode("ACU_SteerCtrl", {"SteerEnable": 1, "SteerAngleTarget": 1.0, "SteerAngleSpeed": 57.3})
    rx.decode(genuine)
    forged = rx.decode(CounterCopyingInjector(profile, math.radians(3.0)).forge(genuine))
    assert forged.signals["SteerLife"] == 1 and forged.signals["SteerAngleTarget"] == pytest.approx(4.0)
    with pytest.raises(FrameRejected, match="counter"):
        rx.decode(tx.encode("ACU_SteerCtrl", {"SteerEnable": 1}))  # the genuine successor is now stale


@pytest.mark.parametrize("period", [0.2, 0.02])
def test_integrity_checks_accept_every_forged_frame_and_secoc_rejects_every_one(period):
    integrity = measure_injection("ld3-dev", period)
    secoc = measure_injection("ld3-dev-secoc", period)
    baseline = measure_injection("ld3-dev-secoc", None)
    assert integrity.injected == secoc.injected == round(4.0 / period)
    assert integrity.accepted == integrity.injected
    assert abs(integrity.offset_m) > 0.1  # pushed sideways
    assert secoc.accepted == 0 and secoc.rejected == {"mac": secoc.injected}
    assert secoc.offset_m == baseline.offset_m == 0.0  # the car never saw a forged command
    if period == 0.2:
        assert integrity.faults == secoc.faults == ()  # slow enough to stay under the frame-rate guard
    else:
        assert "foreign_node" in secoc.faults  # a flood still e-stops, as it does without SecOC


def test_study_prints_one_row_per_profile_and_rate(capsys):
    assert main(["--profile", "ld3-dev-secoc", "--period", "0.2", "--seconds", "1"]) == 0
    rows = [line for line in capsys.readouterr().out.splitlines() if line.startswith("| ld3-dev-secoc")]
    assert rows == ["| ld3-dev-secoc | 1 per 200 ms | 0 of 5 | mac: 5 | none | 0.000 m |"]


def test_a_steer_message_without_a_counter_has_nothing_to_copy(tmp_path):
    root = tmp_path / "no-counter"
    shutil.copytree(PROFILES_DIR / "ld3-dev", root)
    toml = root / "profile.toml"
    toml.write_text(toml.read_text().replace('counter = "SteerLife", ', ""))
    with pytest.raises(ValueError, match="ACU_SteerCtrl carries no counter"):
        CounterCopyingInjector(load_profile(str(root)), 0.05)
