"""Executor doubles for the campaign tests: module-level, so that spawned workers import them. Run as a module
(`python -m tests.eval.campaign.campaign_helpers OUT`) it is a campaign process for the kill test to kill."""

from __future__ import annotations

import logging
import multiprocessing as mp
import os
import signal
import sys
import time
from pathlib import Path

from testbed.eval.campaign.driver import CampaignRun, run_campaign
from testbed.eval.run.scenario import load_scenario
from testbed.eval.run.summary import RunSummary
from tests.eval.run.summary_helpers import write_fake_summary

PARTS = 20
PART_PERIOD_S = 0.05


def _log(path: Path, line: str) -> None:
    """Append one line in one write (O_APPEND), safe with several writers."""
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_APPEND)
    try:
        os.write(fd, f"{line}\n".encode())
    finally:
        os.close(fd)


def warning_writer(run: CampaignRun, run_dir: Path) -> RunSummary:
    """Logs a warning naming the run (as the loop's fault log does), then writes its summary (its scenario: the
    run id)."""
    logging.getLogger("testbed.defense.faults").warning("t=1.000 no-lane-lines: %s", run.run_id)
    return write_fake_summary(run_dir, scenario=run.run_id)


def slow_writer(run: CampaignRun, run_dir: Path) -> RunSummary:
    """Writes `part-0` … `part-19` 0.05 s apart, then summary.json (its scenario: the run id), then logs the run id in
    `completed.log` beside the run folders. Tags: `fail` raises, `die` ends the process, `hang` sleeps (after
    logging its pid and its start on the system's monotonic clock in `pids.log`), `deaf` sleeps with SIGALRM
    blocked (no in-process alarm ends it)."""
    if run.tags.get("fail"):
        raise RuntimeError("boom\nsecond line")
    if run.tags.get("die"):
        os._exit(3)
    if run.tags.get("deaf"):
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGALRM})
        time.sleep(120.0)
    if run.tags.get("hang"):
        _log(run_dir.parent / "pids.log", f"{os.getpid()} {time.monotonic()!r}")
        time.sleep(120.0)
    for i in range(run.tags.get("parts", PARTS)):
        (run_dir / f"part-{i}").write_text(f"{run.run_id} {i}\n")
        time.sleep(PART_PERIOD_S)
    summary = write_fake_summary(run_dir, scenario=run.run_id)
    _log(run_dir.parent / "completed.log", run.run_id)
    return summary


def process_probe(run: CampaignRun, run_dir: Path) -> RunSummary:
    """Records the process it runs in and how many child processes that process has (as the summary's
    attack_state)."""
    return write_fake_summary(run_dir, attack_state={"pid": os.getpid(), "children": len(mp.active_children())})


def warm_up_probe(run: CampaignRun, run_dir: Path) -> RunSummary:
    """Records the process it runs in and whether it had loaded the simulated run's modules (the local backend's
    warm-up) before this run (as the summary's attack_state)."""
    from testbed.eval.campaign.local_backend import WARM_UP_MODULE

    return write_fake_summary(run_dir, attack_state={"pid": os.getpid(), "loaded": WARM_UP_MODULE in sys.modules})


def thread_probe(run: CampaignRun, run_dir: Path) -> RunSummary:
    """Records how many threads torch computes on in the process it runs in (as the summary's attack_state)."""
    import torch

    return write_fake_summary(run_dir, attack_state={"torch_threads": torch.get_num_threads()})


def crash_runs(n: int = 8) -> list[CampaignRun]:
    sc = load_scenario("slr")
    return [CampaignRun(f"run-{i}", sc, {"i": i}) for i in range(n)]


if __name__ == "__main__":
    run_campaign(crash_runs(), Path(sys.argv[1]), workers=2, progress=False, execute=slow_writer)
