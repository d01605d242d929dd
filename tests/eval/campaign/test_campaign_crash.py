"""Crash safety of campaigns: temporary folders renamed into place, a killed campaign leaves no writer, runs
redone and reported by name, per-run time limits, workers=1 in-process."""

import json
import multiprocessing as mp
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from testbed.eval.campaign.driver import CampaignBusyError, CampaignRun, _folder_lock, run_campaign
from testbed.eval.run.scenario import load_scenario
from tests.eval.campaign.campaign_helpers import (
    PARTS,
    crash_runs,
    process_probe,
    slow_writer,
    warm_up_probe,
    warning_writer,
)

ROOT = Path(__file__).resolve().parents[3]


def _files(out: Path) -> dict[str, tuple[int, int]]:
    """Every file under `out` (lock excluded) with its mtime (ns) and size."""
    return {str(p.relative_to(out)): (p.stat().st_mtime_ns, p.stat().st_size) for p in out.rglob("*")
            if p.is_file() and p.name != ".campaign.lock"}


def _in_place(out: Path) -> set[str]:
    return {p.parent.name for p in out.glob("run-*/summary.json")}


def _temps(out: Path) -> list[str]:
    return sorted(p.name for p in out.glob(".run-*.tmp-*"))


def _headers(failures: Path) -> list[str]:
    return [line for line in failures.read_text().splitlines() if not line.startswith(" ")]


def test_a_killed_campaign_leaves_no_writer_and_a_restart_finishes_every_run_once(tmp_path):
    out = tmp_path / "c"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.Popen([sys.executable, "-m", "tests.eval.campaign.campaign_helpers", str(out)], cwd=ROOT, env=env)
    try:
        deadline = time.monotonic() + 60.0
        while not (len(_in_place(out)) >= 2 and _temps(out)):  # killed with runs done and runs under way
            assert proc.poll() is None and time.monotonic() < deadline, "the campaign never got under way"
            time.sleep(0.01)
        proc.send_signal(signal.SIGKILL)
        killed_at = time.time_ns()
    finally:
        proc.kill()
        proc.wait()
    time.sleep(1.0)  # a surviving worker writes a part every 0.05 s
    after_kill = _files(out)
    time.sleep(1.0)
    assert _files(out) == after_kill
    late = {name: mtime for name, (mtime, _) in after_kill.items() if mtime > killed_at + 300_000_000}
    assert not late, f"written more than 0.3 s after the kill: {late}"
    counted, leftovers = _in_place(out), _temps(out)
    assert leftovers and 2 <= len(counted) < 8
    completed_before = (out / "completed.log").read_text().split()

    done = run_campaign(crash_runs(), out, workers=2, progress=False, execute=slow_writer)

    assert [r.run_id for r, _ in done] == [f"run-{i}" for i in range(8)]
    assert not _temps(out)
    for run, summary in done:
        assert summary.scenario == run.run_id
        assert {p.name for p in (out / run.run_id).iterdir()} == {"summary.json"} | {f"part-{i}" for i in range(PARTS)}
    completed_after = (out / "completed.log").read_text().split()[len(completed_before):]
    assert not counted & set(completed_after), "a run counted before the kill was run again"
    assert sorted(completed_after) == sorted(set(completed_after))  # nothing ran twice in the restart
    assert set(completed_after) | counted == _in_place(out)
    redone = (out / "redone.txt").read_text()
    for name in leftovers:
        assert f"removed the unfinished temporary folder {name}" in redone
    lines = (out / "runs.csv").read_text().splitlines()
    assert len(lines) == 9 and len(set(lines)) == 9


def test_a_corrupt_or_incomplete_run_is_redone_and_named(tmp_path, capsys):
    sc = load_scenario("slr")
    runs = [CampaignRun(run_id, sc, {"parts": 1}) for run_id in ("a", "b", "grp/c")]
    run_campaign(runs, tmp_path, workers=1, progress=False, execute=slow_writer)
    assert not (tmp_path / "redone.txt").exists()
    summary = tmp_path / "a" / "summary.json"
    summary.write_text(summary.read_text()[:10])  # truncated mid-string
    (tmp_path / "b" / "summary.json").unlink()
    (tmp_path / "grp" / ".c.tmp-999999").mkdir()
    (tmp_path / "grp" / ".c.tmp-999999" / "part-0").write_text("stale")
    capsys.readouterr()

    done = run_campaign(runs, tmp_path, workers=1, progress=False, execute=slow_writer)

    assert [r.run_id for r, _ in done] == ["a", "b", "grp/c"]
    redone = (tmp_path / "redone.txt").read_text().splitlines()
    assert redone[0].startswith("a: removed the incomplete run folder (summary.json unreadable (JSONDecodeError: "
                                "Unterminated string")
    assert redone[1:] == ["b: removed the incomplete run folder (summary.json missing); redoing it",
                          "grp/c: removed the unfinished temporary folder .c.tmp-999999"]
    err = capsys.readouterr().err
    assert all(f"{tmp_path.name}: {line}" in err for line in redone)
    assert (tmp_path / "completed.log").read_text().split() == ["a", "b", "a", "b"]  # c was done: not rerun
    assert (tmp_path / "grp" / "completed.log").read_text().split() == ["grp/c"]
    assert not list((tmp_path / "grp").glob(".c.tmp-*"))
    assert json.loads(summary.read_text())["scenario"] == "a"


@pytest.mark.parametrize("workers", [1, 2])
def test_a_run_over_its_time_limit_is_a_failure_and_the_others_complete(tmp_path, workers):
    sc = load_scenario("slr")
    runs = [CampaignRun("hang", sc, {"hang": True}), CampaignRun("fail", sc, {"fail": True}),
            *(CampaignRun(f"ok{i}", sc, {"parts": 2}) for i in range(3))]
    done = run_campaign(runs, tmp_path, workers=workers, progress=False, execute=slow_writer, timeout=6.0)
    ended = time.monotonic()
    assert [r.run_id for r, _ in done] == ["ok0", "ok1", "ok2"]
    assert sorted(_headers(tmp_path / "failures.txt")) == ["fail: RuntimeError: boom second line",
                                                           "hang: RunTimeout: over its 6 s limit"]
    assert not list(tmp_path.glob(".*.tmp-*"))
    pid_text, started_text = (tmp_path / "pids.log").read_text().split()
    pid, hang_started = int(pid_text), float(started_text)
    assert 6.0 <= ended - hang_started < 6.0 + 4.0  # cut at its limit, counted from its start (not the workers')
    assert pid == os.getpid() if workers == 1 else pid != os.getpid()
    if workers > 1:
        with pytest.raises(ProcessLookupError):
            os.kill(pid, 0)  # the stuck worker was killed


def test_a_worker_that_dies_is_a_failure_and_is_replaced(tmp_path):
    sc = load_scenario("slr")
    runs = [CampaignRun("die", sc, {"die": True}), *(CampaignRun(f"ok{i}", sc, {"parts": 1}) for i in range(3))]
    done = run_campaign(runs, tmp_path, workers=2, progress=False, execute=slow_writer)
    assert [r.run_id for r, _ in done] == ["ok0", "ok1", "ok2"]
    assert _headers(tmp_path / "failures.txt") == ["die: WorkerDied: the worker exited with code 3"]


def test_workers_1_runs_in_this_process_without_a_pool(tmp_path):
    runs = [CampaignRun(f"r{i}", load_scenario("slr"), {}) for i in range(2)]
    done = run_campaign(runs, tmp_path, workers=1, progress=False, execute=process_probe)
    assert [s.attack_state for _, s in done] == [{"pid": os.getpid(), "children": 0}] * 2


def test_one_campaign_process_per_folder(tmp_path):
    runs = [CampaignRun("a", load_scenario("slr"), {"parts": 1})]
    with _folder_lock(tmp_path), pytest.raises(CampaignBusyError, match="in use by another campaign"):
        run_campaign(runs, tmp_path, workers=1, progress=False, execute=slow_writer)
    assert not (tmp_path / "a").exists()


def test_ld3_campaign_passes_timeout_and_refuses_a_busy_folder(tmp_path, monkeypatch, capsys):
    from testbed import cli
    from testbed.eval.experiments import campaigns

    seen = {}

    def fake_run_campaign(runs, out, **kwargs):
        seen.update(kwargs, runs=[r.run_id for r in runs])
        return []

    monkeypatch.setattr(campaigns, "run_campaign", fake_run_campaign)
    argv = ["campaign", "table4", "--runs", "ld3-start6", "--out", str(tmp_path), "--workers", "1"]
    assert cli.main([*argv, "--timeout", "5"]) == 0
    assert (seen["runs"], seen["timeout"], seen["workers"]) == (["ld3-start6"], 5.0, 1)
    assert cli.main(argv) == 0 and seen["timeout"] is None
    monkeypatch.undo()
    capsys.readouterr()
    with _folder_lock(tmp_path):
        assert cli.main(argv) == cli.EXIT_USAGE
    assert capsys.readouterr().err == f"ld3: error: campaign folder {tmp_path} is in use by another campaign process\n"


def test_a_run_limit_counts_from_the_run_start_not_the_worker_start_up(tmp_path):
    """The executor's module sleeps longer than the limit at import; its runs (about 0.1 s each) are done."""
    from tests.eval.campaign.slow_import_executor import IMPORT_DELAY_S, quick_writer

    sc = load_scenario("slr")
    runs = [CampaignRun(f"ok{i}", sc, {"parts": 2}) for i in range(3)]
    done = run_campaign(runs, tmp_path, workers=2, progress=False, execute=quick_writer,
                        timeout=IMPORT_DELAY_S / 2)
    assert [r.run_id for r, _ in done] == ["ok0", "ok1", "ok2"]
    assert not (tmp_path / "failures.txt").exists()


@pytest.mark.parametrize("workers", [1, 2])
def test_warnings_a_run_logs_go_to_its_run_log_not_the_console(tmp_path, capfd, workers):
    runs = [CampaignRun(f"w{i}", load_scenario("slr"), {}) for i in range(2)]
    done = run_campaign(runs, tmp_path, workers=workers, progress=False, execute=warning_writer)
    assert len(done) == 2
    for i in range(2):
        assert (tmp_path / f"w{i}" / "run.log").read_text() == (
            f"WARNING testbed.defense.faults: t=1.000 no-lane-lines: w{i}\n")
    out, err = capfd.readouterr()
    assert "no-lane-lines" not in out + err


def test_workers_kept_warm_serve_every_batch_and_a_dead_one_is_replaced(tmp_path):
    from testbed.eval.campaign.driver import campaign_backend

    sc = load_scenario("slr")

    def batch(name: str, n: int, **tags) -> list[int]:
        runs = [CampaignRun(f"{name}{i}", sc, dict(tags)) for i in range(n)]
        done = run_campaign(runs, tmp_path / name, workers=2, progress=False, execute=process_probe)
        return sorted(s.attack_state["pid"] for _, s in done)

    cold = [batch("cold-a", 4), batch("cold-b", 4)]
    assert not set(cold[0]) & set(cold[1])  # without: each batch starts its own workers
    with campaign_backend("local", None).kept_warm():
        first, second = set(batch("a", 4)), set(batch("b", 4))
        assert first == second and len(first) == 2 and os.getpid() not in first
        died = run_campaign([CampaignRun("die", sc, {"die": True})], tmp_path / "c", workers=2, progress=False,
                            execute=slow_writer)
        assert died == []
        third = set(batch("d", 4))
        assert len(third) == 2 and len(third & first) == 1  # the survivor stays; the dead one is replaced
    for pid in third:
        with pytest.raises(ProcessLookupError):
            for _ in range(50):  # stopped when the outermost kept_warm ends
                os.kill(pid, 0)
                time.sleep(0.1)


def test_workers_started_ahead_load_the_simulation_and_serve_the_first_batch(tmp_path):
    from testbed.eval.campaign.driver import campaign_backend

    sc = load_scenario("slr")
    runs = [CampaignRun(f"r{i}", sc, {}) for i in range(4)]
    before = {p.pid for p in mp.active_children()}
    with campaign_backend("local", None).kept_warm(2, start=True):
        ahead = {p.pid for p in mp.active_children()} - before
        assert len(ahead) == 2  # started on entering, before any batch
        done = run_campaign(runs, tmp_path / "warm", workers=2, progress=False, execute=warm_up_probe)
        assert {s.attack_state["pid"] for _, s in done} == ahead
        assert all(s.attack_state["loaded"] for _, s in done)  # loaded before its first run arrived
    assert not ahead & {p.pid for p in mp.active_children()}


def test_workers_started_ahead_are_not_more_in_flight_than_a_batch_asks(tmp_path):
    from testbed.eval.campaign.driver import campaign_backend

    sc = load_scenario("slr")
    with campaign_backend("local", None).kept_warm(3, start=True):
        done = run_campaign([CampaignRun(f"r{i}", sc, {}) for i in range(6)], tmp_path, workers=2,
                            progress=False, execute=process_probe)
    assert len(done) == 6 and len({s.attack_state["pid"] for _, s in done}) == 2


def test_workers_started_ahead_end_at_once_when_the_caller_fails():
    from testbed.errors import UserError
    from testbed.eval.campaign.driver import campaign_backend

    before = {p.pid for p in mp.active_children()}
    with pytest.raises(UserError, match="bad input"), campaign_backend("local", None).kept_warm(2, start=True):
        ahead = {p.pid for p in mp.active_children()} - before
        t0 = time.monotonic()
        raise UserError("bad input")
    assert time.monotonic() - t0 < 1.0  # killed, not waited for while they still load the simulation
    assert len(ahead) == 2 and not ahead & {p.pid for p in mp.active_children()}
