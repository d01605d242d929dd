import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from testbed.defense.attack_detection import Cusum, Ld3Detector, cusum_alarm_index


def test_alarm_index_hand_computed():
    # b = 0.6, tau = 0.1
    # S0 = max(0, 0 + 0.65 - 0.6) = 0.05
    # S1 = max(0, 0.05 + 0.10 - 0.6) = 0        (the clamp at 0 matters here)
    # S2 = max(0, 0 + 0.68 - 0.6) = 0.08
    # S3 = 0.08 + 0.69 - 0.6 = 0.17 > 0.1 -> alarm at index 3
    residuals = [0.65, -0.10, -0.68, 0.69, 0.70]
    assert cusum_alarm_index(residuals, 0.6, 0.1) == 3
    c = Cusum(0.6, 0.1)
    alarms = [c.update(r) for r in residuals]
    assert alarms == [False, False, False, True, True]
    assert c.statistic == pytest.approx(0.17)  # frozen at the alarm value after index 3


def test_statistic_equal_to_threshold_is_no_alarm():
    # S = 0.7 - 0.6 = 0.1 (to rounding, 0.0999...) is not > 0.1; the next 0.65 gives 0.15 > 0.1
    assert cusum_alarm_index([0.7, 0.65], 0.6, 0.1) == 1
    assert cusum_alarm_index([0.5, 0.6, 0.55], 0.6, 0.1) is None


def test_reset_clears_statistic_and_alarm():
    c = Cusum(0.6, 0.1)
    assert c.update(1.0)  # S = 0.4 > 0.1
    c.reset()
    assert not c.alarmed and c.statistic == 0.0
    assert not c.update(0.65)  # S = 0.05


def test_ld3_detector_uses_deviation_difference():
    d = Ld3Detector(b=0.6, tau=0.1)
    # r = D_MSF - D_LD: 0.3 - (-0.2) = 0.5 -> S = 0; 0.5 - (-0.3) = 0.8 -> S = 0.2 > 0.1
    assert not d.update(0.3, -0.2)
    assert d.update(0.5, -0.3)
    assert d.statistic == pytest.approx(0.2)


@given(st.lists(st.floats(-3.0, 3.0), max_size=40), st.floats(0.0, 1.0), st.floats(0.0, 1.0))
@settings(max_examples=60, deadline=None)
def test_offline_index_matches_online_detector(residuals, b, tau):
    c = Cusum(b, tau)
    online = next((i for i, r in enumerate(residuals) if c.update(r)), None)
    assert cusum_alarm_index(residuals, b, tau) == online
