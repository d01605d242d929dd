"""Report-rate guard: receive stalls up to the slack, however often, pass; a second sender is caught in time."""

from __future__ import annotations

import random

import pytest

from hil.link.report_rate import ReportRateGuard

CYCLE = 0.02


def _feed(guard: ReportRateGuard, times: list[float]) -> list[bool]:
    return [guard.arrive(0x100, t) for t in sorted(times)]


def _stalled(sent: list[float], slack: int, rng: random.Random) -> list[float]:
    """Receive times of frames sent at `sent`: the receiver now and then sleeps up to `slack` cycles and then
    reads the queue at once."""
    received, wake = [], 0.0
    for t in sent:
        if t >= wake and rng.random() < 0.05:
            wake = t + rng.uniform(0.0, slack * CYCLE)
        received.append(max(t, wake) + rng.uniform(0.0, 0.002))
    return received


def test_a_steady_stream_with_repeated_receive_stalls_up_to_the_slack_never_alarms():
    guard = ReportRateGuard({0x100}, CYCLE, slack_cycles=5)
    sent = [i * CYCLE for i in range(20_000)]
    assert all(_feed(guard, _stalled(sent, 5, random.Random(3))))


def test_a_stream_slower_than_nominal_never_alarms_and_a_slightly_faster_one_is_allowed():
    for period in (CYCLE * 1.3, CYCLE * 0.995):
        guard = ReportRateGuard({0x100}, CYCLE, slack_cycles=5)
        assert all(_feed(guard, [i * period for i in range(20_000)]))


@pytest.mark.parametrize("offset", [0.0, 0.5])
def test_a_second_sender_at_the_same_rate_alarms_within_twice_the_slack(offset):
    guard = ReportRateGuard({0x100}, CYCLE, slack_cycles=5)
    ours = [i * CYCLE for i in range(200)]
    foreign = [(100 + i + offset) * CYCLE for i in range(100)]
    verdicts = _feed(guard, ours + foreign)
    first_alarm = sorted(ours + foreign)[verdicts.index(False)]
    assert 100 * CYCLE < first_alarm <= (100 + 2 * 5 + 1) * CYCLE


def test_the_slack_follows_the_report_timeout_and_nonsense_is_refused():
    assert ReportRateGuard.for_timeout({1}, 0.02, 0.1).slack == 5
    assert ReportRateGuard.for_timeout({1}, 0.02, 0.001).slack == 1
    with pytest.raises(ValueError):
        ReportRateGuard({1}, 0.0, 5)
