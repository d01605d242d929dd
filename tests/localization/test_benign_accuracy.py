"""Benign MSF accuracy in the closed loop: lateral error RMS <= 0.10 m and max <= 0.30 m."""

import numpy as np
import pytest

from tests.localization.harness import Lane, banded_quality, run_closed_loop


def constant_quality(q: float):
    return lambda lane: lambda x, y: q


@pytest.mark.parametrize(
    ("lane", "speed", "quality", "seed"),
    [
        (Lane(), 12.0, banded_quality(), 0),
        (Lane(600.0), 27.0, banded_quality(), 1),
        (Lane(600.0), 20.0, constant_quality(0.55), 2),
    ],
)
def test_benign_lateral_error(lane, speed, quality, seed):
    run = run_closed_loop(lane, speed, 40.0, seed, quality=quality).arrays()
    err = run["msf_lat_err"][100:]
    assert float(np.sqrt(np.mean(err**2))) <= 0.10
    assert float(np.max(np.abs(err))) <= 0.30
