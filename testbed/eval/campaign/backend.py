"""Where a campaign's runs execute: the `CampaignBackend` contract that the built-in `local` and `ray` backends
and third-party ones (entry-point group `ld3.campaign_backends`, e.g. a cluster scheduler) implement.

A backend executes a batch of runs and yields each one's outcome as it finishes, with the run's files in its
temporary folder `temp_dir(out, run_id)`; the campaign process then settles the run (renames the folder into
place or removes it) exactly as for every other backend, so a backend never writes a final run folder.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import ClassVar, NamedTuple

from testbed.errors import UserError
from testbed.eval.campaign.run import CampaignRun, RunExecutor
from testbed.registry import Capability

DEFAULT_WORKERS = 2


class BackendUnavailable(UserError):
    """The chosen campaign backend cannot run here (its optional dependency is missing, its cluster cannot be
    reached)."""


class RunOutcome(NamedTuple):
    """A finished run and its failure record (None: its executor returned; its files are in its temporary
    folder)."""

    run: CampaignRun
    error: str | None


class CampaignBackend(ABC):
    """A registered campaign backend: a name, one line of help, whether it takes a cluster `address`, and how
    it runs a batch. `workers` is the most runs in flight (None: the backend's default)."""

    name: ClassVar[str]
    help: ClassVar[str]
    needs: ClassVar[frozenset[Capability]] = frozenset()
    connects: ClassVar[bool] = False
    """Whether the backend takes a cluster address (`--address`)."""
    draws: ClassVar[bool] = False
    """Whether `run` takes its batch as any iterable and draws each run from it only when the run can start (a
    `RunQueue` makes its runs then); a backend that does not is given a list, every run made first."""

    def check(self, address: str | None) -> None:
        """Raise BackendUnavailable (one line naming the fix) when the backend cannot run here; called before
        the campaign takes its folder, so that nothing is written. Must return within seconds. The base class
        has nothing to check."""
        return None

    @contextmanager
    def kept_warm(self, workers: int | None = None, *, start: bool = False) -> Iterator[None]:
        """Within it, what the backend starts for one batch (worker processes, a cluster connection) may serve
        the next batches too (a search asks for its trials in batches); with `start`, a backend may start it at
        once for `workers` in flight (None: its default), so that its start overlaps the caller's own set-up
        before the first batch. The base class keeps and starts nothing."""
        yield

    @abstractmethod
    def run(self, batch: Iterable[CampaignRun], out: Path, execute: RunExecutor, timeout: float | None,
            workers: int | None, address: str | None) -> Iterator[RunOutcome]:
        """Execute each run of `batch` (a list unless the backend `draws`) with `execute` into
        `temp_dir(out, run.run_id)` within its `run_limit`, yielding its outcome as it finishes (a run that fails,
        times out or loses its worker is an outcome with its failure record, never an exception). Closing the
        iterator stops the runs still in flight."""
