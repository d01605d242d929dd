"""Campaigns: many scenario runs, each in its own folder; crash-safe and resumable.

Each run is written into a temporary sibling folder `.<name>.tmp-<pid>` and renamed into place by the
campaign process only once its executor has returned and its `summary.json` reads back as a JSON object, so
a run folder in place is complete and only such a folder counts as done; a rerun skips it. At start, a
leftover temporary folder, or a run folder whose summary.json is missing or unreadable, is removed (the run
is redone) and named on stderr and in `redone.txt`. A run that fails or exceeds its time limit (`timeout`,
default `run_timeout`) is named on stderr and in `failures.txt` (first line `run_id: ErrorType: message`,
the traceback tail indented below it) and the campaign goes on; both files describe the latest invocation.
Warnings a run logs go to its own `run.log`, not the console.

On the `local` backend with workers > 1, runs go to spawned worker processes (one OpenMP thread each, as on
Ray) that die with the campaign process (PR_SET_PDEATHSIG on Linux, else a watchdog on the parent's pid), so
killing the campaign leaves at most temporary folders; a worker over its time limit is killed and replaced.
With workers = 1 runs execute in this process. On the `ray` backend runs are Ray tasks whose files come back
to this process, which writes and settles them the same way (`testbed.eval.ray_backend`). One campaign process
at a time may use a folder (`.campaign.lock`). The collected summaries go to `runs.csv` (nested fields as
dotted columns) and the campaign's own table to `report.md`.
"""

from __future__ import annotations

import csv
import ctypes
import json
import logging
import multiprocessing as mp
import os
import shutil
import signal
import sys
import threading
import time
import traceback
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import contextmanager, suppress
from dataclasses import dataclass
from multiprocessing.connection import Connection, wait
from pathlib import Path
from typing import Any

from tqdm import tqdm

from testbed.errors import UserError
from testbed.eval.scenario import Scenario

try:
    import fcntl
except ImportError:  # not POSIX: no folder lock
    fcntl = None  # type: ignore[assignment]

TMP_MARK = ".tmp-"
RUN_LOG = "run.log"
LOCK_NAME = ".campaign.lock"
SETUP_ALLOWANCE_S = 120.0
SIM_TIME_FACTOR = 10.0
"""Default time limit = SETUP_ALLOWANCE_S + SIM_TIME_FACTOR × simulated duration; the slowest campaign runs
measured (75 neural-detector campaign runs) took 3.3 × their simulated time."""
PR_SET_PDEATHSIG = 1
WATCHDOG_PERIOD_S = 0.2
BACKENDS = ("local", "ray")
WORKER_THREAD_VARIABLES = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")
DEFAULT_WORKERS = 2
STARTED = "started"
"""What a worker answers first on receiving a run (its imports done): the run's time limit counts from here."""


@dataclass(frozen=True)
class CampaignRun:
    run_id: str
    scenario: Scenario
    tags: dict[str, Any]


RunExecutor = Callable[[CampaignRun, Path], dict[str, Any]]
"""Runs one campaign run into the folder it is given (a temporary folder, already created) and returns its
summary; it must write summary.json there. A module-level function, so that worker processes can import it."""


class RunTimeout(BaseException):
    """A run went past its time limit (a BaseException, so that an executor's `except Exception` cannot
    swallow it)."""


class CampaignBusyError(RuntimeError):
    """Another campaign process holds the folder's lock."""


class BackendUnavailable(UserError):
    """The chosen campaign backend cannot run here (its optional dependency is not installed)."""


def run_and_write(run: CampaignRun, run_dir: Path) -> dict[str, Any]:
    """The default executor: the run's standard outputs into the campaign's temporary run folder."""
    from testbed.eval.runner import run_into

    return run_into(run.scenario, run_dir).summary


def run_timeout(run: CampaignRun) -> float:
    """The default time limit of a run (s): set-up allowance plus a generous multiple of its simulated time."""
    return SETUP_ALLOWANCE_S + SIM_TIME_FACTOR * run.scenario.duration


def temp_dir(out: Path, run_id: str) -> Path:
    """The temporary folder this process writes run `run_id` into, beside its final folder."""
    final = out / run_id
    return final.parent / f".{final.name}{TMP_MARK}{os.getpid()}"


def load_summary(run_dir: Path) -> dict[str, Any] | str:
    """The run's summary, or why there is none (summary.json missing, unreadable or not a JSON object)."""
    try:
        summary = json.loads((run_dir / "summary.json").read_text())
    except FileNotFoundError:
        return "summary.json missing"
    except (OSError, ValueError) as exc:
        return f"summary.json unreadable ({type(exc).__name__}: {exc})"
    return summary if isinstance(summary, dict) else "summary.json is not a JSON object"


def failure_record(run_id: str, error: str, message: str, tail: str = "") -> str:
    """`run_id: ErrorType: message` on one line, then `tail` (a traceback tail) indented by four spaces."""
    lines = [f"{run_id}: {error}: {' '.join(message.split())}"]
    lines += [f"    {line}" for line in tail.splitlines() if line.strip()]
    return "\n".join(lines)


def run_limit(run: CampaignRun, timeout: float | None) -> float:
    """The time limit of `run` (s): `timeout`, or its default `run_timeout`."""
    return timeout if timeout is not None else run_timeout(run)


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path)
    else:
        path.unlink(missing_ok=True)


@contextmanager
def _run_log(run_dir: Path) -> Iterator[None]:
    """Send the warnings logged while a run executes to `run_dir`/RUN_LOG (created on the first one) instead of
    the console, where a campaign's runs would interleave them with its progress bar."""
    handler = logging.FileHandler(run_dir / RUN_LOG, delay=True)
    handler.setLevel(logging.WARNING)
    handler.setFormatter(logging.Formatter("%(levelname)s %(name)s: %(message)s"))
    root = logging.getLogger()
    root.addHandler(handler)
    try:
        yield
    finally:
        root.removeHandler(handler)
        handler.close()


def attempt(execute: RunExecutor, run: CampaignRun, tmp: Path) -> str | None:
    """Run the executor into `tmp` (its warnings into RUN_LOG there); None on success, else its failure record
    (no Exception escapes)."""
    try:
        with _run_log(tmp):
            execute(run, tmp)
        return None
    except Exception as exc:  # a failing run is reported, never allowed to sink the campaign
        frames = traceback.StackSummary.from_list(traceback.extract_tb(exc.__traceback__)[-3:]).format()
        return failure_record(run.run_id, type(exc).__name__, str(exc), "".join(frames))


def settle(run: CampaignRun, out: Path, tmp: Path, error: str | None) -> str | None:
    """Rename a finished run's temporary folder into place, or remove it; returns the failure record if any."""
    if error is None and isinstance(problem := load_summary(tmp), str):
        error = failure_record(run.run_id, "IncompleteRun", f"the executor returned but {problem}")
    if error is None:
        try:
            os.rename(tmp, out / run.run_id)
        except OSError as exc:
            error = failure_record(run.run_id, type(exc).__name__, f"cannot move the run into place: {exc}")
    if error is not None:
        _remove(tmp)
    return error


@contextmanager
def _folder_lock(out: Path) -> Iterator[None]:
    """Hold `out`'s campaign lock (the OS releases it when this process dies), or raise CampaignBusyError."""
    if fcntl is None:
        yield
        return
    with (out / LOCK_NAME).open("a") as fh:
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise CampaignBusyError(f"campaign folder {out} is in use by another campaign process") from None
        yield


def check_campaign_dir(out: Path) -> None:
    """A one-line UserError unless `out` is new, empty, or a campaign's folder (it holds the campaign lock):
    a campaign cleans up run folders it finds incomplete, which must never be someone else's files."""
    if out.is_symlink() or (out.exists() and not out.is_dir()):
        raise UserError(f"--out {out} is a file, not a folder; choose a folder")
    if out.is_dir() and any(out.iterdir()) and not (out / LOCK_NAME).exists():
        raise UserError(f"--out {out} holds files that are not a campaign's; choose a new or empty folder")


def _sweep(runs: Sequence[CampaignRun], out: Path) -> list[str]:
    """Remove the runs' leftover temporary folders and incomplete run folders; `run_id: what` for each."""
    leftovers: dict[Path, list[Path]] = {}
    for parent in {(out / r.run_id).parent for r in runs}:
        for entry in parent.iterdir() if parent.is_dir() else ():
            if entry.name.startswith(".") and TMP_MARK in entry.name:
                leftovers.setdefault(parent / entry.name[1:entry.name.rindex(TMP_MARK)], []).append(entry)
    redone = []
    for run in runs:
        final = out / run.run_id
        for tmp in sorted(leftovers.get(final, [])):
            _remove(tmp)
            redone.append(f"{run.run_id}: removed the unfinished temporary folder {tmp.name}")
        if final.exists() and isinstance(problem := load_summary(final), str):
            _remove(final)
            redone.append(f"{run.run_id}: removed the incomplete run folder ({problem}); redoing it")
    return redone


def _write_record(path: Path, entries: list[str]) -> None:
    """`entries` into `path`, or no file when there are none (the latest invocation's record)."""
    if entries:
        path.write_text("\n".join(entries) + "\n")
    else:
        path.unlink(missing_ok=True)


def run_campaign(runs: Sequence[CampaignRun], out: Path, workers: int | None = None, progress: bool = True,
                 execute: RunExecutor = run_and_write, timeout: float | None = None, backend: str = "local",
                 address: str | None = None) -> list[tuple[CampaignRun, dict[str, Any]]]:
    """Run every campaign run not yet done with `execute`, each within `timeout` seconds (default
    `run_timeout` per run), on `backend`; returns (run, summary) for all runs that are done.

    `local`: `workers` (default 2) spawned worker processes, or this process for 1. `ray`: Ray tasks on the
    cluster at `address`, at most `workers` at a time (default: all of its CPUs), or on a local Ray instance
    with `workers` (default 2) CPUs when `address` is None; see `testbed.eval.ray_backend`."""
    if timeout is not None and not timeout > 0:
        raise UserError(f"timeout must be > 0 s, got {timeout}")
    if workers is not None and workers < 1:
        raise UserError(f"workers must be ≥ 1, got {workers}")
    if backend not in BACKENDS:
        raise UserError(f"unknown campaign backend {backend!r}: choose one of {', '.join(BACKENDS)}")
    if address is not None and backend != "ray":
        raise UserError(f"a cluster address ({address!r}) needs the ray backend: add --backend ray")
    if backend == "ray":
        from testbed.eval.ray_backend import require_ray

        require_ray()
    check_campaign_dir(out)
    out.mkdir(parents=True, exist_ok=True)
    with _folder_lock(out):
        redone = _sweep(runs, out)
        for line in redone:
            print(f"{out.name}: {line}", file=sys.stderr)
        _write_record(out / "redone.txt", redone)
        todo = [r for r in runs if not (out / r.run_id).exists()]
        with tqdm(total=len(todo), desc=out.name, disable=not progress or not todo) as bar:
            failures = _dispatch(todo, out, execute, timeout, workers, backend, address, bar) if todo else []
        _write_record(out / "failures.txt", failures)
        done = [(run, summary) for run in runs if isinstance(summary := load_summary(out / run.run_id), dict)]
        _write_runs_csv(out / "runs.csv", done)
    return done


def _dispatch(todo: Sequence[CampaignRun], out: Path, execute: RunExecutor, timeout: float | None,
              workers: int | None, backend: str, address: str | None, bar: tqdm) -> list[str]:
    """The runs on the chosen backend; returns the failure records."""
    if backend == "ray":
        from testbed.eval.ray_backend import run_on_ray

        return run_on_ray(todo, out, execute, timeout, workers, address, bar)
    n_workers = DEFAULT_WORKERS if workers is None else workers
    if n_workers == 1:
        return _run_in_process(todo, out, execute, timeout, bar)
    return _run_in_workers(todo, out, execute, timeout, n_workers, bar)


def count_finished(bar: tqdm, failures: list[str], error: str | None) -> None:
    """One more run finished: advance the bar; a failure is kept and its first line shown on stderr."""
    bar.update(1)
    if error is not None:
        failures.append(error)
        tqdm.write(error.splitlines()[0], file=sys.stderr)


# ---- workers = 1: in this process ---------------------------------------------------------------------
@contextmanager
def _alarm(seconds: float) -> Iterator[None]:
    """Raise RunTimeout in the main thread after `seconds` (SIGALRM). In-process so that a script without a
    `__main__` guard, a debugger or a notebook work as they are; the alarm interrupts Python code and blocking
    system calls, not one long C call. An outer alarm (pytest-timeout's) is re-armed afterwards, deferred by
    at most `seconds`. Off the main thread no signal can be used: there the run has no limit."""
    if threading.current_thread() is not threading.main_thread() or not hasattr(signal, "setitimer"):
        yield
        return

    def expire(signum: int, frame: object) -> None:
        raise RunTimeout(f"over its {seconds:g} s limit")

    previous = signal.signal(signal.SIGALRM, expire)
    t0 = time.monotonic()
    outer_delay, outer_interval = signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        try:
            signal.setitimer(signal.ITIMER_REAL, 0)
        finally:
            signal.signal(signal.SIGALRM, previous)
            if outer_delay > 0:
                signal.setitimer(signal.ITIMER_REAL, max(outer_delay - (time.monotonic() - t0), 1e-3),
                                 outer_interval)


def _run_in_process(todo: Sequence[CampaignRun], out: Path, execute: RunExecutor, timeout: float | None,
                    bar: tqdm) -> list[str]:
    """Each run in this process, one after the other, within its limit; returns the failure records."""
    failures: list[str] = []
    for run in todo:
        tmp = temp_dir(out, run.run_id)
        tmp.mkdir(parents=True)
        count_finished(bar, failures, settle(run, out, tmp, attempt_within(execute, run, tmp,
                                                                           run_limit(run, timeout))))
    return failures


def attempt_within(execute: RunExecutor, run: CampaignRun, tmp: Path, limit_s: float) -> str | None:
    """`attempt` in this process under `_alarm(limit_s)`; a run over the limit is a RunTimeout record."""
    try:
        with _alarm(limit_s):
            return attempt(execute, run, tmp)
    except RunTimeout as exc:
        return failure_record(run.run_id, "RunTimeout", str(exc))


# ---- workers > 1: spawned worker processes --------------------------------------------------------------
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


def _worker_main(conn: Connection, parent_pid: int) -> None:
    """A worker: run each (run, temporary folder, executor) received and answer its failure record or None."""
    _die_with_parent(parent_pid)
    _one_thread()
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

    def stop(self) -> None:
        """End the worker; a busy one is killed and its temporary folder removed."""
        if self.job is not None:
            self.kill()
            _remove(self.job.tmp)
            return
        with suppress(OSError):  # already gone
            self.conn.send(None)
        self.process.join(5.0)
        if self.process.is_alive():
            self.kill()


def _run_in_workers(todo: Sequence[CampaignRun], out: Path, execute: RunExecutor, timeout: float | None,
                    n_workers: int, bar: tqdm) -> list[str]:
    """The runs on up to `n_workers` spawned workers; a worker that dies or times out is replaced."""
    ctx = mp.get_context("spawn")
    pending = list(reversed(todo))
    pool: list[_Worker] = []
    failures: list[str] = []
    try:
        while True:
            pool = [w for w in pool if w.job is not None or w.process.is_alive()]
            while len(pool) < min(n_workers, len(pending) + sum(w.job is not None for w in pool)):
                pool.append(_Worker.start(ctx))
            for worker in pool:
                if pending and worker.job is None:
                    run = pending.pop()
                    worker.give(run, out, execute, run_limit(run, timeout))
            busy = [(w, w.job) for w in pool if w.job is not None]
            if not busy:
                return failures
            ready = wait([w.conn for w, _ in busy] + [w.process.sentinel for w, _ in busy],
                         max(0.0, min(job.deadline for _, job in busy) - time.monotonic()))
            now = time.monotonic()
            for worker, job in busy:
                finished, error = worker.outcome(job, ready, now)
                if finished:
                    worker.job = None
                    count_finished(bar, failures, settle(job.run, out, job.tmp, error))
    finally:
        for worker in pool:
            worker.stop()


def flatten(value: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """Nested dicts as dotted keys (`attack.kind`, `defense_params.b`); lists as JSON text."""
    flat: dict[str, Any] = {}
    for key, item in value.items():
        name = f"{prefix}{key}"
        if isinstance(item, dict):
            flat.update(flatten(item, f"{name}."))
        elif isinstance(item, list):
            flat[name] = json.dumps(item)
        else:
            flat[name] = item
    return flat


def _write_runs_csv(path: Path, done: Iterable[tuple[CampaignRun, dict[str, Any]]]) -> None:
    rows = [{"run_id": r.run_id, **r.tags, **flatten(s)} for r, s in done]
    if not rows:
        return
    keys: list[str] = []
    for row in rows:
        keys += [k for k in row if k not in keys]
    with path.open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=keys)
        writer.writeheader()
        writer.writerows(rows)
