"""The `local` campaign backend: runs on this machine.

With workers > 1, runs go to spawned worker processes (one OpenMP thread each, as on Ray) that die with the
campaign process (PR_SET_PDEATHSIG on Linux, else a watchdog on the parent's pid), so killing the campaign
leaves at most temporary folders; a worker over its time limit is killed and replaced. Within `kept_warm` the
idle workers outlive a batch and take the next one's runs (a search's batches). With workers = 1 runs
execute in this process, one after the other, under an alarm (so that a script without a `__main__` guard, a
debugger or a notebook work as they are).
"""

from __future__ import annotations

import ctypes
import importlib
import multiprocessing as mp
import os
import signal
import sys
import threading
import time
from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager, suppress
from dataclasses import dataclass
from multiprocessing.connection import Connection, wait
from pathlib import Path
from typing import Any

from testbed.eval.campaign.backend import DEFAULT_WORKERS, CampaignBackend, RunOutcome
from testbed.eval.campaign.run import (
    SETUP_ALLOWANCE_S,
    CampaignRun,
    RunExecutor,
    attempt,
    attempt_within,
    failure_record,
    remove_path,
    run_limit,
    temp_dir,
)

PR_SET_PDEATHSIG = 1
WATCHDOG_PERIOD_S = 0.2
WORKER_THREAD_VARIABLES = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")
WARM_UP_MODULE = "testbed.eval.run.runner"
"""What a worker imports as it starts (the simulated run: world, loop, attacks, defenses, outputs)."""
STARTED = "started"
"""What a worker answers first on receiving a run (its imports done): the run's time limit counts from here."""


class LocalBackend(CampaignBackend):
    """`workers` (default 2) spawned worker processes, or this process for 1."""

    name = "local"
    help = "worker processes on this machine (default 2; 1: every run in this process)"
    draws = True

    def __init__(self) -> None:
        self._warm: list[_Worker] | None = None

    def run(self, batch: Iterable[CampaignRun], out: Path, execute: RunExecutor, timeout: float | None,
            workers: int | None, address: str | None) -> Iterator[RunOutcome]:
        n_workers = DEFAULT_WORKERS if workers is None else workers
        if n_workers == 1:
            return _run_in_process(batch, out, execute, timeout)
        return _run_in_workers(batch, out, execute, timeout, n_workers, self._warm)

    @contextmanager
    def kept_warm(self, workers: int | None = None, *, start: bool = False) -> Iterator[None]:
        """Workers started for one batch stay for the next (their imports and what they keep, such as the
        controller's gain schedules, paid once), until the outermost `kept_warm` ends. With `start` (and more
        than one worker), the workers are spawned at once and load the simulation's modules while the caller
        prepares its first batch."""
        if self._warm is not None:
            yield
            return
        self._warm = []
        try:
            n_workers = DEFAULT_WORKERS if workers is None else workers
            if start and n_workers > 1:
                ctx = mp.get_context("spawn")
                self._warm.extend(_Worker.start(ctx) for _ in range(n_workers))
            yield
        except BaseException:  # the caller failed (bad input, an interrupt): no need to wait for a warm-up
            warm, self._warm = self._warm, None
            for worker in warm:
                worker.kill()
            raise
        finally:
            if self._warm is not None:
                warm, self._warm = self._warm, None
                _stop_all(warm)


def _run_in_process(batch: Iterable[CampaignRun], out: Path, execute: RunExecutor, timeout: float | None,
                    ) -> Iterator[RunOutcome]:
    """Each run in this process, one after the other, within its limit."""
    for run in batch:
        tmp = temp_dir(out, run.run_id)
        tmp.mkdir(parents=True)
        yield RunOutcome(run, attempt_within(execute, run, tmp, run_limit(run, timeout)))


def _die_with_parent(parent_pid: int) -> None:
    """Make this worker die with the campaign process: PR_SET_PDEATHSIG (SIGKILL) on Linux, else a thread
    polling the parent's pid; a worker whose parent is already gone exits at once."""
    armed = False
    if sys.platform.startswith("linux"):
        armed = ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGKILL) == 0
    if not armed:
        threading.Thread(target=_watch_parent, args=(parent_pid,), daemon=True).start()
    if os.getppid() != parent_pid:
        os._exit(1)


def _watch_parent(parent_pid: int) -> None:
    while os.getppid() == parent_pid:
        time.sleep(WATCHDOG_PERIOD_S)
    os._exit(1)


def _one_thread() -> None:
    """One OpenMP/MKL thread in this worker (torch's lane detector included), as Ray gives its workers: a
    worker is one core's worth of work beside the others."""
    os.environ.update({name: "1" for name in WORKER_THREAD_VARIABLES})
    if "torch" in sys.modules:  # already loaded (a parent's __main__ that imports it): the variables came late
        sys.modules["torch"].set_num_threads(1)


def _load_simulation() -> None:
    """Import the modules every simulated run needs (`WARM_UP_MODULE`) before the first run arrives: a worker
    started ahead of its batch loads them while the campaign process is still busy. A module that fails to
    import is left for the first run to report."""
    with suppress(Exception):
        importlib.import_module(WARM_UP_MODULE)


def _worker_main(conn: Connection, parent_pid: int) -> None:
    """A worker: run each (run, temporary folder, executor) received and answer its failure record or None."""
    _die_with_parent(parent_pid)
    _one_thread()
    _load_simulation()
    while True:
        try:
            job = conn.recv()
        except EOFError:
            return
        if job is None:
            return
        run, tmp, execute = job
        conn.send(STARTED)
        conn.send(attempt(execute, run, tmp))


@dataclass
class _Job:
    """A run given to a worker: its limit counts from the worker's STARTED answer; until then (spawning,
    imports) the deadline allows SETUP_ALLOWANCE_S more."""

    run: CampaignRun
    tmp: Path
    limit_s: float
    deadline: float


@dataclass
class _Worker:
    """A spawned worker process fed one run at a time over a pipe."""

    process: Any
    conn: Connection
    job: _Job | None = None

    @classmethod
    def start(cls, ctx: Any) -> _Worker:
        conn, child = ctx.Pipe()
        process = ctx.Process(target=_worker_main, args=(child, os.getpid()), daemon=True)
        process.start()
        child.close()
        return cls(process, conn)

    def give(self, run: CampaignRun, out: Path, execute: RunExecutor, limit_s: float) -> None:
        self.job = _Job(run, temp_dir(out, run.run_id), limit_s, time.monotonic() + SETUP_ALLOWANCE_S + limit_s)
        self.job.tmp.mkdir(parents=True)
        with suppress(OSError):  # a worker that is gone is reported by its sentinel
            self.conn.send((run, self.job.tmp, execute))

    def outcome(self, job: _Job, ready: list[Any], now: float) -> tuple[bool, str | None]:
        """(finished, failure record) of `job`: the worker's answer, its death, or its timeout (the worker is
        killed then). The STARTED answer moves the deadline to its arrival plus the run's limit."""
        gone = self.process.sentinel in ready
        while self.conn in ready or self.conn.poll():
            try:
                answer = self.conn.recv()
            except EOFError:
                gone = True
                break
            if answer != STARTED:
                return True, answer
            job.deadline = time.monotonic() + job.limit_s
            ready = [r for r in ready if r is not self.conn]
        if not gone:
            if now < job.deadline:
                return False, None
            self.kill()
            return True, failure_record(job.run.run_id, "RunTimeout", f"over its {job.limit_s:g} s limit")
        self.process.join()
        return True, failure_record(job.run.run_id, "WorkerDied", f"the worker exited with code "
                                                                  f"{self.process.exitcode}")

    def kill(self) -> None:
        self.process.kill()
        self.process.join()
        self.conn.close()

    def ask_to_stop(self) -> None:
        """Tell an idle worker to exit (`wait_stopped` waits for it); a busy one is killed and its temporary folder
        removed at once."""
        if self.job is not None:
            self.kill()
            remove_path(self.job.tmp)
            self.job = None
            return
        with suppress(OSError):  # already gone
            self.conn.send(None)

    def wait_stopped(self) -> None:
        """Wait up to 5 s for a worker told to stop to exit, then kill it."""
        self.process.join(5.0)
        if self.process.is_alive():
            self.kill()


def _stop_all(workers: Sequence[_Worker]) -> None:
    """Stop the workers together: each is told first, so that they wind down at the same time."""
    for worker in workers:
        worker.ask_to_stop()
    for worker in workers:
        worker.wait_stopped()


def _run_in_workers(batch: Iterable[CampaignRun], out: Path, execute: RunExecutor, timeout: float | None,
                    n_workers: int, warm: list[_Worker] | None = None) -> Iterator[RunOutcome]:
    """The runs on up to `n_workers` spawned workers, each run drawn from `batch` when a worker is free for it; a
    worker that dies or times out is replaced. With `warm` (the workers kept between batches) idle workers are
    taken from it and left in it at the end; without, every worker is stopped at the end."""
    ctx = mp.get_context("spawn")
    pending = iter(batch)
    drawn_all = False
    pool: list[_Worker] = [] if warm is None else warm
    try:
        while True:
            pool = [w for w in pool if w.job is not None or w.process.is_alive()]
            while not drawn_all and sum(w.job is not None for w in pool) < n_workers:
                run = next(pending, None)
                if run is None:
                    drawn_all = True
                    break
                worker = next((w for w in pool if w.job is None), None)
                if worker is None:
                    worker = _Worker.start(ctx)
                    pool.append(worker)
                worker.give(run, out, execute, run_limit(run, timeout))
            busy = [(w, w.job) for w in pool if w.job is not None]
            if not busy:
                return
            ready = wait([w.conn for w, _ in busy] + [w.process.sentinel for w, _ in busy],
                         max(0.0, min(job.deadline for _, job in busy) - time.monotonic()))
            now = time.monotonic()
            for worker, job in busy:
                finished, error = worker.outcome(job, ready, now)
                if finished:
                    worker.job = None
                    yield RunOutcome(job.run, error)
    finally:
        kept = [w for w in pool if warm is not None and w.job is None and w.process.is_alive()]
        _stop_all([w for w in pool if w not in kept])
        if warm is not None:
            warm[:] = kept
