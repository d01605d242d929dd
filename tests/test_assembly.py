"""`LoopRun`: the duration is loop time, not a count of rows; a stop ends after standing still."""

import pytest

from testbed.assembly import STANDSTILL_HOLD_S, LoopRun
from testbed.loop import TickRecord


class FakeLoop:
    """Ticks at `dt` whose clock may jump (a late tick on a vehicle); brakes to 0 from `stop_at` s."""

    def __init__(self, dt: float, jumps: dict[int, float] | None = None, stop_at: float | None = None) -> None:
        self.dt, self.t, self.n = dt, 0.0, 0
        self.jumps, self.stop_at = jumps or {}, stop_at
        self.stopping = False
        self.chassis = self

    def latched_faults(self):
        return ()

    def tick(self) -> TickRecord:
        self.t += self.jumps.get(self.n, 0.0)
        self.stopping = self.stop_at is not None and self.t >= self.stop_at
        rec = TickRecord(self.t, 0, 0, 0, 0.0 if self.stopping else 4.0, None, None, None, None, "normal", 0, 0)
        self.t += self.dt
        self.n += 1
        return rec


def _run(loop, duration):
    run = LoopRun(loop, duration)
    while not run.done:
        run.step()
    return run


def test_the_duration_is_time_on_the_loops_clock():
    assert len(_run(FakeLoop(0.025), 20.0).rows) == 800
    late = _run(FakeLoop(0.025, jumps={100: 5.0}), 20.0)  # ticks that came late do not stretch the drive
    assert late.ended_by == "duration" and late.elapsed_s == pytest.approx(20.0, abs=0.025)
    assert len(late.rows) == 600


def test_a_stop_ends_the_run_after_standing_still():
    run = _run(FakeLoop(0.025, stop_at=2.0), 20.0)
    assert run.ended_by == "standstill" and run.stop_t == pytest.approx(2.0, abs=0.026)
    assert run.rows[-1].t - run.stop_t == pytest.approx(STANDSTILL_HOLD_S, abs=0.026)
