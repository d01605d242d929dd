"""Operator interruption of a run: SIGINT or SIGTERM calls `on_interrupt` with the signal's name (the bridge
latches `interrupted`, the loop brakes in lane and the run ends with its outputs); a second signal raises
KeyboardInterrupt to cut the braking short."""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Callable, Iterator
from types import FrameType

SIGNALS = (signal.SIGINT, signal.SIGTERM)


@contextlib.contextmanager
def interruptible(on_interrupt: Callable[[str], None]) -> Iterator[None]:
    """Within the block, the first SIGINT/SIGTERM calls `on_interrupt(name)` and the next raises
    KeyboardInterrupt; the previous handlers come back after it. Outside the main thread it changes nothing."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    received: list[str] = []

    def handler(signum: int, _frame: FrameType | None) -> None:
        if received:
            raise KeyboardInterrupt
        received.append(signal.Signals(signum).name)
        on_interrupt(received[0])

    previous = {signum: signal.signal(signum, handler) for signum in SIGNALS}
    try:
        yield
    finally:
        for signum, old in previous.items():
            signal.signal(signum, old)
