"""Outputs survive hostile ends: SIGTERM cleans up as Ctrl-C does (no temporary folder left, an earlier run kept
under --force), and inputs that only look hostile (odd file names, a CAN log stamped hours ahead) run."""

from __future__ import annotations

import contextlib
import io
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from testbed.cli import main
from tests.cli.case import make_files
from tests.cli.hostile_inputs import ACCEPTED

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("case", ACCEPTED, ids=[c.id for c in ACCEPTED])
def test_valid_input_that_looks_hostile_runs(case, tmp_path, monkeypatch):
    make_files(tmp_path, case.files, case.links)
    monkeypatch.chdir(tmp_path)
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        started = time.monotonic()
        code = main([a.replace("{ws}", str(tmp_path)) for a in case.argv])
    assert code == 0, err.getvalue()
    assert case.says in out.getvalue()
    assert time.monotonic() - started < 60


def test_sigterm_leaves_no_temporary_folder_and_keeps_the_earlier_run(tmp_path):
    out = tmp_path / "run"
    make_files(out, {"summary.json": '{"scenario": "earlier"}', "trajectory.csv": "t\n0.0\n"})
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    # a slow car on a long drive (about 5 s of loop), signalled once its folder is claimed and the modules the run
    # imports while it builds (matplotlib's compiled parts among them) are in: the signal lands in the loop, not in
    # an import or after the run is done
    proc = subprocess.Popen([sys.executable, "-m", "testbed.cli", "run", "slr", "--duration", "600", "--speed", "2",
                             "--out", str(out), "--force"], cwd=tmp_path, env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while not list(tmp_path.glob(".run.tmp-*")) and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.2)
    assert list(tmp_path.glob(".run.tmp-*")), "the run never started writing"
    time.sleep(1.5)
    assert proc.poll() is None, "the run ended before it was signalled"
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert "interrupted" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]
    assert (out / "summary.json").read_text() == '{"scenario": "earlier"}'


def test_a_run_set_aside_by_a_killed_command_is_named_not_overwritten(tmp_path):
    from testbed.errors import UserError
    from testbed.eval.run.folder import claimed_out_dir

    out, aside = tmp_path / "run", tmp_path / ".run.old-999999999"
    make_files(tmp_path, {"run/can.asc": "partial", ".run.old-999999999/summary.json": "{}"})
    with pytest.raises(UserError, match="set aside by a command that died"), claimed_out_dir(out, force=True):
        pass
    assert (aside / "summary.json").read_text() == "{}"


def test_sigterm_that_surfaces_as_another_exception_is_reported_as_the_interrupt(monkeypatch, capsys):
    import testbed.cli as cli

    def import_interrupted(args):
        try:  # as a compiled module's initialisation does with the KeyboardInterrupt raised inside it
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(5)
        except KeyboardInterrupt:
            raise ImportError("initialization failed") from None
        return 0

    monkeypatch.setattr(cli, "cmd_scenarios", import_interrupted)
    assert main(["scenarios"]) == 130
    assert "interrupted" in capsys.readouterr().err
    monkeypatch.setattr(cli, "cmd_scenarios", lambda args: 1 / 0)
    assert main(["scenarios"]) == cli.EXIT_INTERNAL  # the next command's own bug is still one
