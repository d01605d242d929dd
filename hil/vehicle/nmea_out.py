"""GNSS fixes as NMEA 0183 GGA sentences (pynmeagps, high-precision coordinates): what a receiver would send
for a fix in the map's world frame, its covariance expressed as HDOP at a stated fix quality."""

from __future__ import annotations

import math
import time

from pynmeagps import GET, NMEAMessage

from hil.vehicle.geodetic import LocalTangentPlane
from hil.vehicle.nmea_gnss import UERE_M
from testbed.localization.sensors import GnssFix

RTK_FLOAT = 5


def gga_sentence(fix: GnssFix, plane: LocalTangentPlane, quality: int = RTK_FLOAT, satellites: int = 14) -> bytes:
    """One $GPGGA line for `fix`: position on `plane`, HDOP = √(mean of the covariance's diagonal) / UERE of
    `quality` (so the reader maps it back to the same σ), UTC time of day of `fix.t` seconds after midnight."""
    lat, lon = plane.to_latlon(float(fix.xy[0]), float(fix.xy[1]))
    std = math.sqrt(0.5 * float(fix.cov[0, 0] + fix.cov[1, 1]))
    hdop = round(std / UERE_M[quality], 2)
    stamp = time.strftime("%H:%M:%S", time.gmtime(fix.t)) + f"{fix.t % 1.0:.2f}"[1:]
    message = NMEAMessage("GP", "GGA", GET, hpnmeamode=True, time=stamp, lat=abs(lat), NS="N" if lat >= 0 else "S",
                          lon=abs(lon), EW="E" if lon >= 0 else "W", quality=quality, numSV=satellites,
                          HDOP=max(hdop, 0.01), alt=0.0, altUnit="M", sep=0.0, sepUnit="M", diffAge="",
                          diffStation="")
    return message.serialize()
