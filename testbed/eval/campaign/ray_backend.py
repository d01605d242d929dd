"""The `ray` campaign backend: each run is a Ray task that executes into a scratch folder on its node and
returns the folder's files; the campaign process writes them into the run's temporary folder and settles
it exactly as for the local backend (rename into place, failures.txt, redone runs, the folder lock).

At most `workers` tasks are in flight (default: every CPU of the cluster), one CPU each. A task keeps its
run's time limit itself, counted from when it starts executing (as the in-process local backend does);
a task still unfinished `START_ALLOWANCE_S` after its limit, counted from submission, is cancelled with its
worker process killed (a hang in one long C call). Workers never touch the campaign folder, so killing the
campaign leaves no writer there. Within `kept_warm` the connection (and with it Ray's worker processes, their
imports and what they keep, such as the controller's gain schedules) stays from one batch to the next. A
cluster address is probed with a plain TCP connection first (Ray itself retries an address nobody answers for
minutes), so a dead one is refused within `CONNECT_TIMEOUT_S`. Needs the optional extra: `pip install '.[ray]'`.
"""

from __future__ import annotations

import logging
import socket
import tempfile
import time
from collections.abc import Iterable, Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Any
from urllib.parse import urlsplit

from testbed.errors import UserError
from testbed.eval.campaign.backend import DEFAULT_WORKERS, BackendUnavailable, CampaignBackend, RunOutcome
from testbed.eval.campaign.run import CampaignRun, RunExecutor, attempt_within, failure_record, run_limit, temp_dir

INSTALL_HINT = "pip install '.[ray]'"
START_ALLOWANCE_S = 60.0
"""What a task may take beyond its run's limit, counted from submission, before it is cancelled: a worker
process to start and import the testbed (2.8 s on the idle 2-core development machine, over 8 s at a load
average of 30)."""
CONNECT_TIMEOUT_S = 3.0
"""How long the probe of a cluster address waits for a TCP connection."""
LOCAL_ADDRESSES = ("auto", "local")
"""Addresses Ray resolves on this machine (and refuses at once when nothing runs there): not probed."""
GCS_PORT, CLIENT_PORT = 6379, 10001
"""Ray's default ports of a head node (`HOST`) and of its Ray Client server (`ray://HOST`)."""


class RayBackend(CampaignBackend):
    """Ray tasks on the cluster at `address`, at most `workers` at a time (default: all of its CPUs), or on a
    local Ray instance with `workers` (default 2) CPUs when `address` is None."""

    name = "ray"
    help = f"Ray tasks on a local Ray instance or the cluster at --address (needs {INSTALL_HINT})"
    connects = True
    draws = True

    def __init__(self) -> None:
        self._warm: ExitStack | None = None
        self._connection: tuple[str | None, int | None, int] | None = None
        """Within `kept_warm`: the (address, workers) the kept connection was made for, and its task slots."""

    def check(self, address: str | None) -> None:
        require_ray()
        if address is not None:
            probe(address)

    def run(self, batch: Iterable[CampaignRun], out: Path, execute: RunExecutor, timeout: float | None,
            workers: int | None, address: str | None) -> Iterator[RunOutcome]:
        ray = require_ray()
        if self._warm is None:
            return _run_connected(ray, batch, out, execute, timeout, workers, address)
        return _run_tasks(ray, batch, out, execute, timeout, self._kept_slots(ray, address, workers))

    def _kept_slots(self, ray: ModuleType, address: str | None, workers: int | None) -> int:
        """The task slots of the kept connection, connecting (or reconnecting, for another address or number of
        workers) first."""
        if self._connection is not None and self._connection[:2] != (address, workers):
            self._warm.close()
            self._connection = None
        if self._connection is None:
            self._connection = (address, workers, self._warm.enter_context(connected(ray, address, workers)))
        return self._connection[2]

    @contextmanager
    def kept_warm(self, workers: int | None = None, *, start: bool = False) -> Iterator[None]:
        """The Ray connection made for one batch serves the next ones, until the outermost `kept_warm` ends (a
        local instance started for it is shut down then). `start` is not used: the first batch connects (its
        address comes with the batch)."""
        if self._warm is not None:
            yield
            return
        self._warm = ExitStack()
        try:
            yield
        finally:
            warm, self._warm, self._connection = self._warm, None, None
            warm.close()


def probe(address: str) -> None:
    """BackendUnavailable unless something accepts a TCP connection at the Ray `address` (`HOST[:PORT]` or
    `ray://HOST[:PORT]`) within CONNECT_TIMEOUT_S; the addresses Ray resolves locally are left to Ray."""
    if address in LOCAL_ADDRESSES:
        return
    client = address.startswith("ray://")
    try:
        where = urlsplit("//" + address.removeprefix("ray://"))
        host, port = where.hostname, where.port or (CLIENT_PORT if client else GCS_PORT)
    except ValueError as exc:
        raise BackendUnavailable(f"cannot read the Ray cluster address {address!r}: {exc}") from None
    if not host:
        raise BackendUnavailable(f"cannot read the Ray cluster address {address!r}: no host")
    try:
        socket.create_connection((host, port), timeout=CONNECT_TIMEOUT_S).close()
    except OSError as exc:
        raise BackendUnavailable(f"cannot connect to the Ray cluster at {address!r}: nothing answers at "
                                 f"{host}:{port} ({exc.strerror or type(exc).__name__})") from None


def require_ray() -> ModuleType:
    """The `ray` module, or BackendUnavailable naming the install command."""
    try:
        import ray
    except ImportError:
        raise BackendUnavailable(f"the ray backend needs Ray, which is not installed: {INSTALL_HINT}") from None
    return ray


def execute_in_scratch(execute: RunExecutor, run: CampaignRun, limit_s: float,
                       ) -> tuple[str | None, dict[str, bytes]]:
    """The body of a run's task: `execute` into a fresh scratch folder within `limit_s` (counted from here);
    (failure record or None, the folder's files by relative POSIX path; none after a failure)."""
    with tempfile.TemporaryDirectory(prefix="ld3-run-") as scratch:
        run_dir = Path(scratch) / "run"
        run_dir.mkdir()
        error = attempt_within(execute, run, run_dir, limit_s)
        if error is not None:
            return error, {}
        return None, {p.relative_to(run_dir).as_posix(): p.read_bytes()
                      for p in sorted(run_dir.rglob("*")) if p.is_file()}


def write_files(folder: Path, files: dict[str, bytes]) -> None:
    """A task's files (relative POSIX path → bytes) written under `folder`."""
    for rel, data in files.items():
        path = folder / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)


@contextmanager
def connected(ray: ModuleType, address: str | None, workers: int | None) -> Iterator[int]:
    """Ray connected to `address`, or a local instance with `workers` CPUs; yields the number of tasks to
    keep in flight. A connection this process already holds is used as it is (then `address` must be None)
    and left open; one made here is shut down on leaving."""
    if ray.is_initialized():
        if address is not None:
            raise UserError(f"Ray is already connected in this process; leave the address ({address!r}) unset "
                             "to use that connection, or call ray.shutdown() first")
        yield workers or _cluster_cpus(ray)
        return
    if address is None:
        ray.init(num_cpus=workers or DEFAULT_WORKERS, include_dashboard=False, logging_level=logging.WARNING)
    else:
        try:
            ray.init(address=address, logging_level=logging.WARNING)
        except (ConnectionError, ValueError) as exc:
            raise BackendUnavailable(f"cannot connect to the Ray cluster at {address!r}: {exc}") from None
    try:
        yield workers or _cluster_cpus(ray)
    finally:
        ray.shutdown()


def _cluster_cpus(ray: ModuleType) -> int:
    cpus = int(ray.cluster_resources().get("CPU", 0))
    if cpus < 1:
        raise UserError("the Ray cluster has no CPU to run campaign tasks on; add worker nodes or set --workers")
    return cpus


@dataclass(frozen=True)
class _Task:
    run: CampaignRun
    limit_s: float
    deadline: float


def _outcome(ray: ModuleType, ref: Any, run: CampaignRun) -> tuple[str | None, dict[str, bytes]]:
    """A finished task's (failure record, files); a task that died or failed inside Ray is a failure."""
    try:
        return ray.get(ref)
    except ray.exceptions.WorkerCrashedError as exc:
        return failure_record(run.run_id, "WorkerDied", str(exc).splitlines()[0]), {}
    except ray.exceptions.RayError as exc:
        return failure_record(run.run_id, type(exc).__name__, str(exc).splitlines()[0] if str(exc) else ""), {}


def _place(run: CampaignRun, out: Path, error: str | None, files: dict[str, bytes]) -> RunOutcome:
    """A finished task's files into the run's temporary folder; its outcome."""
    tmp = temp_dir(out, run.run_id)
    tmp.mkdir(parents=True)
    try:
        write_files(tmp, files)
    except OSError as exc:
        error = error or failure_record(run.run_id, type(exc).__name__, f"cannot write the run's files: {exc}")
    return RunOutcome(run, error)


def _run_connected(ray: ModuleType, batch: Iterable[CampaignRun], out: Path, execute: RunExecutor,
                   timeout: float | None, workers: int | None, address: str | None) -> Iterator[RunOutcome]:
    """The runs as Ray tasks on a connection of their own (see the module docstring)."""
    with connected(ray, address, workers) as slots:
        yield from _run_tasks(ray, batch, out, execute, timeout, slots)


def _run_tasks(ray: ModuleType, batch: Iterable[CampaignRun], out: Path, execute: RunExecutor,
               timeout: float | None, slots: int) -> Iterator[RunOutcome]:
    """The runs as Ray tasks on the open connection, at most `slots` in flight, each drawn from `batch` when a
    slot is free for it (see the module docstring)."""
    task = ray.remote(num_cpus=1, max_retries=0)(execute_in_scratch)
    pending = iter(batch)
    drawn_all = False
    in_flight: dict[Any, _Task] = {}
    try:
        while True:
            while not drawn_all and len(in_flight) < slots:
                run = next(pending, None)
                if run is None:
                    drawn_all = True
                    break
                limit = run_limit(run, timeout)
                in_flight[task.remote(execute, run, limit)] = _Task(run, limit, time.monotonic() + limit
                                                                    + START_ALLOWANCE_S)
            if not in_flight:
                return
            wait_s = max(0.0, min(t.deadline for t in in_flight.values()) - time.monotonic())
            ready, _ = ray.wait(list(in_flight), num_returns=1, timeout=wait_s)
            for ref in ready:
                job = in_flight.pop(ref)
                error, files = _outcome(ray, ref, job.run)
                yield _place(job.run, out, error, files)
            now = time.monotonic()
            for ref, job in list(in_flight.items()):
                if now >= job.deadline:
                    ray.cancel(ref, force=True)
                    del in_flight[ref]
                    yield RunOutcome(job.run, failure_record(
                        job.run.run_id, "RunTimeout", f"over its {job.limit_s:g} s limit (+ "
                                                      f"{START_ALLOWANCE_S:g} s to start, cancelled)"))
    finally:
        for ref in in_flight:
            ray.cancel(ref, force=True)
