"""Realtime scheduling of a vehicle run's threads: asked for, said when refused, and given back."""

import os
import threading

import pytest

from hil.link import scheduling
from hil.link.scheduling import normal_scheduling, realtime_scheduling


def _in_thread(work):
    out = []
    thread = threading.Thread(target=lambda: out.append(work()))
    thread.start()
    thread.join()
    return out[0]


def test_no_priority_leaves_the_thread_alone():
    assert realtime_scheduling(None) == "normal" and realtime_scheduling(0) == "normal"


def test_a_refusal_is_said_not_raised(monkeypatch):
    def refuse(*_):
        raise PermissionError(1, "Operation not permitted")

    monkeypatch.setattr(scheduling.os, "sched_setscheduler", refuse)
    assert realtime_scheduling(10) == "normal (SCHED_FIFO 10 refused: [Errno 1] Operation not permitted)"


@pytest.mark.skipif(not hasattr(os, "sched_setscheduler"), reason="Linux scheduling")
def test_the_thread_gets_fifo_where_permitted_and_gives_it_back():
    def work():
        said = realtime_scheduling(3)
        during = os.sched_getscheduler(0)
        normal_scheduling()
        return said, during, os.sched_getscheduler(0)

    said, during, after = _in_thread(work)
    if said.startswith("normal"):
        pytest.skip(f"no realtime privilege here: {said}")
    assert (said, during, after) == ("SCHED_FIFO 3", os.SCHED_FIFO, os.SCHED_OTHER)
