import math

import pytest

from testbed.defense.uncertainty import DeviationUncertainty


def test_alg4_uncertainties_hand_computed():
    u = DeviationUncertainty(window=3, lam=0.8)
    # 1: s_msf = 0.2, s_ld = 0.1, g = sqrt(0.02); f_msf = 0.2/g = sqrt(2), f_ld = 0.1/g = 1/sqrt(2)
    #    R = 0.8 f + 0.2 * 0.1
    r = u.update(0.2, -0.1, 0.1, 0.1)
    assert r.r_msf == pytest.approx(0.8 * math.sqrt(2) + 0.02)
    assert r.r_ld == pytest.approx(0.8 / math.sqrt(2) + 0.02)
    u.update(0.4, -0.1, 0.1, 0.1)
    # 3: s_msf = 0.2 + 0.4 + 0.6 = 1.2, s_ld = 0.1 + 0.1 + 0.2 = 0.4, g = sqrt(0.48)
    #    f_msf = 1.2 / sqrt(0.48) = sqrt(3), f_ld = 0.4 / sqrt(0.48) = 1/sqrt(3)
    r = u.update(-0.6, 0.2, 0.1, 0.1)
    assert r.r_msf == pytest.approx(0.8 * math.sqrt(3) + 0.02)
    assert r.r_ld == pytest.approx(0.8 / math.sqrt(3) + 0.02)
    # 4: window w = 3 drops the first pair: s_msf = 0.4 + 0.6 + 1.0 = 2.0, s_ld = 0.1 + 0.2 + 0.2 = 0.5
    #    g = 1, f_msf = 2, f_ld = 0.5 -> R_msf = 1.6 + 0.02 = 1.62, R_ld = 0.4 + 0.02 = 0.42
    r = u.update(1.0, -0.2, 0.1, 0.1)
    assert r.r_msf == pytest.approx(1.62)
    assert r.r_ld == pytest.approx(0.42)


def test_lambda_zero_gives_source_uncertainties():
    u = DeviationUncertainty(window=5, lam=0.0)
    assert u.update(1.0, 0.1, 0.3, 0.05) == pytest.approx((0.3, 0.05))


def test_zero_deviation_source_stays_finite():
    u = DeviationUncertainty(window=5, lam=1.0)
    r = u.update(0.0, 0.5, 0.1, 0.1)
    # s_msf floored at 1e-3: f_msf = sqrt(1e-3 / 0.5), f_ld = sqrt(0.5 / 1e-3)
    assert r.r_msf == pytest.approx(math.sqrt(1e-3 / 0.5))
    assert r.r_ld == pytest.approx(math.sqrt(0.5 / 1e-3))


def test_power_two_squares_the_history_term():
    u = DeviationUncertainty(window=3, lam=0.8, power=2.0)
    # s_msf = 0.2, s_ld = 0.1: f_msf = sqrt(2), f_ld = 1/sqrt(2); R = 0.8 f^2 + 0.2 P
    r = u.update(0.2, -0.1, 0.1, 0.3)
    assert r.r_msf == pytest.approx(0.8 * 2.0 + 0.02)
    assert r.r_ld == pytest.approx(0.8 * 0.5 + 0.06)
