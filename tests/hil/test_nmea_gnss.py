"""NMEA GNSS: GGA sentences over a pty become fixes on the map's tangent plane with a covariance from fix
quality and HDOP; bad checksums and sentences without a fix are counted and fuse nothing; a stream that stops
is a stall."""

from __future__ import annotations

import io
import os
import time
import tty

import numpy as np
import pytest
from pynmeagps import GET, NMEAMessage

from hil.geodetic import LocalTangentPlane, parse_origin
from hil.nmea_gnss import NmeaGnssReader, fix_covariance, open_nmea
from hil.nmea_out import gga_sentence
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
    assert reader.counts.fixes == 1 and reader.counts.bad == 1 and reader.counts.no_fix == 1
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
        os.write(master, gga_sentence(sent[0], PLANE))
        reader.take(wait_s=1.0)
        assert reader.stalled(1.4) is None
        why = reader.stalled(2.0)
        assert why is not None and why.startswith("no GNSS fix for 1.5 s (6 fixes")
    finally:
        reader.close()
        reader.stream.close()
        os.close(master)
        os.close(slave)
