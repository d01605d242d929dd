"""Realtime scheduling of the threads that keep a vehicle's timing (the loop, the bridge's command pacer): Linux
SCHED_FIFO at a priority, refused without the privilege (CAP_SYS_NICE or RLIMIT_RTPRIO), in which case the
thread stays at normal priority and the refusal is said, never raised."""

from __future__ import annotations

import os

from hil.link.faults import one_line

RT_PRIORITY = 10
"""SCHED_FIFO priority of a vehicle run's threads from the moment it opens the bus (the bridge's command pacer runs
one above): at normal priority, under CPU load, command cycles went out up to 7 periods apart, and a thread of the
run holding the GIL while the scheduler left it waiting stalled the rest. Without the privilege they run at normal
priority and the summary says so; 0 asks for none."""

MAX_PRIORITY = 98
"""The highest priority a thread may ask for here (99 is left to the kernel's own watchdogs)."""


def realtime_scheduling(priority: int | None) -> str:
    """Put the calling thread under SCHED_FIFO at `priority` (None or 0: leave it); how it is scheduled, in words."""
    if not priority:
        return "normal"
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except (AttributeError, OSError) as exc:
        return f"normal (SCHED_FIFO {priority} refused: {one_line(exc)})"
    return f"SCHED_FIFO {priority}"


def normal_scheduling() -> None:
    """Put the calling thread back under the normal time-sharing scheduler (where it was moved off it)."""
    if hasattr(os, "sched_setscheduler") and os.sched_getscheduler(0) != os.SCHED_OTHER:
        os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
