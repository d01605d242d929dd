"""NMEA GNSS: GGA sentences over a pty become fixes on the map's tangent plane with a covariance from fix
quality and HDOP; bad checksums and sentences without a fix are counted and fuse nothing; hostile sentences with
valid checksums (HDOP, position, time) are refused and counted by reason; a stream that stops or carries only
garbage is a fault; a file plays at its sentences' UTC times."""

from __future__ import annotations

import io
import itertools
import os
import time
import tty

import numpy as np
import pytest
from pynmeagps import GET, NMEAMessage

from hil.vehicle.geodetic import LocalTangentPlane, parse_origin
from hil.vehicle.nmea_gnss import NmeaGnssReader, fix_covariance, open_nmea
from hil.vehicle.nmea_out import gga_sentence
from testbed.localization.sensors import GnssFix

PLANE = LocalTangentPlane(48.137, 11.575)


def test_tangent_plane_round_trips_and_a_degree_of_latitude_is_111_km():
    for east, north in ((0.0, 0.0), (1234.5, -987.25), (-20_000.0, 15_000.0)):
        back = PLANE.to_xy(*PLANE.to_latlon(east, north))
        assert np.allclose(back, (east, north), atol=1e-6)
    assert PLANE.to_xy(49.137, 11.575)[1] == pytest.approx(111_200.0, rel=2e-3)
    assert parse_origin("48.137,11.575") == PLANE
    with pytest.raises(ValueError, match="LAT,LON"):
        parse_origin("48.137")


def test_covariance_is_hdop_times_the_fix_quality_range_error_and_no_fix_is_none():
    assert fix_covariance(4, 1.0)[0, 0] == pytest.approx(0.02**2)
    assert fix_covariance(1, 2.0)[1, 1] == pytest.approx(5.0**2)
    assert fix_covariance(1, 2.0)[0, 0] > fix_covariance(2, 2.0)[0, 0] > fix_covariance(5, 2.0)[0, 0]
    for quality in (0, 6, 7, 8):
        assert fix_covariance(quality, 1.0) is None
    assert fix_covariance(1, 0.0) is None


def test_sentences_become_fixes_and_bad_or_fixless_ones_are_counted():
    good = gga_sentence(GnssFix(3.0, np.array([103.2, -54.31]), np.eye(2) * 0.25**2), PLANE)
    bad_checksum = good[:-4] + b"00\r\n"
    no_fix = NMEAMessage("GP", "GGA", GET, quality=0, HDOP=99.99).serialize()
    other = NMEAMessage("GP", "RMC", GET, status="A", lat=48.1, NS="N", lon=11.5, EW="E").serialize()
    reader = NmeaGnssReader(io.BytesIO(other + bad_checksum + no_fix + good + b"garbage\r\n"), PLANE, lambda: 7.5)
    assert reader.take(wait_s=2.0)
    time.sleep(0.1)
    assert reader.counts.fixes == 1 and reader.counts.no_fix == 1
    assert reader.counts.bad == 2  # the bad checksum and the line of garbage
    assert reader.ended == "end of stream" and reader.last_fix_t == 7.5


def test_a_stream_over_a_pty_arrives_in_order_and_a_silent_one_stalls():
    master, slave = os.openpty()
    tty.setraw(slave)
    now = [0.0]
    reader = NmeaGnssReader(open_nmea(os.ttyname(slave)), PLANE, lambda: now[0], stall_s=1.0)
    try:
        sent = [GnssFix(0.1 * k, np.array([float(k), 2.0 * k]), np.eye(2) * 0.09) for k in range(5)]
        for fix in sent:
            os.write(master, gga_sentence(fix, PLANE))
        got: list[GnssFix] = []
        deadline = time.monotonic() + 3.0
        while len(got) < 5 and time.monotonic() < deadline:
            got += reader.take(wait_s=0.5)
        assert [tuple(np.round(f.xy, 2)) for f in got] == [tuple(f.xy) for f in sent]
        assert all(np.allclose(f.cov, np.eye(2) * 0.09, rtol=0.02) for f in got)
        assert reader.stalled(0.9) is None
        now[0] = 0.5
        os.write(master, gga_sentence(GnssFix(0.5, sent[0].xy, sent[0].cov), PLANE))
        reader.take(wait_s=1.0)
        assert reader.stalled(1.4) is None
        why = reader.stalled(2.0)
        assert why is not None and why.startswith("no GNSS fix for 1.5 s (6 fixes")
    finally:
        reader.close()
        reader.stream.close()
        os.close(master)
        os.close(slave)


def _sentence(body: str) -> bytes:
    """`$body*CS` with a valid checksum: the hostile content is what the reader has to refuse."""
    checksum = 0
    for byte in body.encode():
        checksum ^= byte
    return f"${body}*{checksum:02X}\r\n".encode()


def _gga(utc: str = "120000.00", lat: str = "4808.2200", ns: str = "N", lon: str = "01134.5000", ew: str = "E",
         hdop: str = "1.0", quality: int = 5) -> bytes:
    return _sentence(f"GPGGA,{utc},{lat},{ns},{lon},{ew},{quality},14,{hdop},0.0,M,0.0,M,,")


def _read_all(lines: list[bytes]) -> NmeaGnssReader:
    reader = NmeaGnssReader(io.BytesIO(b"".join(lines)), PLANE, lambda: 1.0)
    deadline = time.monotonic() + 3.0
    while reader.ended is None and time.monotonic() < deadline:
        time.sleep(0.01)
    return reader


@pytest.mark.parametrize(("sentence", "reason"), [
    (_gga(hdop="inf"), "hdop"), (_gga(hdop="nan"), "hdop"), (_gga(hdop="1e-300"), "hdop"),
    (_gga(hdop="0.0"), "hdop"), (_gga(hdop="150"), "hdop"), (_gga(hdop=""), "hdop"),
    (_gga(lat="9908.2200"), "position"), (_gga(lon="19934.5000"), "position"), (_gga(ns="X"), "position"),
    (_gga(lat=""), "position"), (_gga(lat="inf"), "position"),
    (_gga(lat="5808.2200"), "position"),  # 1100 km north of the map's origin
    (_gga(utc=""), "time"), (_gga(utc="993456.78"), "time"),
])
def test_a_hostile_sentence_with_a_valid_checksum_is_refused_and_counted(sentence, reason):
    reader = _read_all([sentence, _gga(utc="120001.00")])
    fixes = reader.take()
    assert reader.counts.refused[reason] == 1 and sum(reader.counts.refused.values()) == 1
    assert len(fixes) == 1 and reader.counts.fixes == 1 and reader.counts.bad == 0
    assert np.all(np.isfinite(fixes[0].xy)) and np.all(np.isfinite(fixes[0].cov)) and fixes[0].cov[0, 0] > 0


def test_a_fix_not_after_the_last_accepted_one_is_refused_but_midnight_rolls_over():
    reader = _read_all([_gga(utc="235959.50"), _gga(utc="235959.50"), _gga(utc="235958.00"), _gga(utc="000000.00")])
    assert reader.counts.fixes == 2 and reader.counts.refused["time"] == 2


def test_a_stream_of_garbage_or_refused_sentences_is_a_fault_at_once():
    garbage = _read_all([b"\x00\xffnoise\r\n"] * 6 + [_gga(hdop="inf")] * 4)
    why = garbage.stalled(1.0)  # within stall_s of the start: the run of bad sentences alone is the fault
    assert why is not None and why.startswith("10 bad or refused NMEA sentences in a row")
    assert "6 bad sentences" in why and "4 hdop" in why
    recovered = _read_all([_gga(hdop="inf")] * 9 + [_gga()])
    assert recovered.stalled(1.0) is None


def test_a_file_plays_at_its_sentences_utc_times(tmp_path):
    path = tmp_path / "drive.nmea"
    path.write_bytes(b"".join(_gga(utc=f"1200{s:05.2f}") for s in (0.0, 0.4, 0.8, 1.2)))
    arrived: list[float] = []
    reader = NmeaGnssReader(open_nmea(str(path)), PLANE, time.monotonic)
    try:
        deadline = time.monotonic() + 5.0
        while len(arrived) < 4 and time.monotonic() < deadline:
            arrived += [fix.t for fix in reader.take(wait_s=0.5)]
    finally:
        reader.close()
        reader.stream.close()
    assert reader.paced and len(arrived) == 4
    assert arrived[-1] - arrived[0] == pytest.approx(1.2, abs=0.15)
    assert [b - a for a, b in itertools.pairwise(arrived)] == pytest.approx([0.4] * 3, abs=0.15)
