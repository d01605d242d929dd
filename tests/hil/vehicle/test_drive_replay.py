"""`ld3 replay`: LD3's detection run again over a simulator-recorded attacked drive (run.mcap's /ld3/input)
alarms when the closed-loop run did, writes the D_MSF / D_LD / CUSUM table and plot, and takes other
[defense] parameters."""

from __future__ import annotations

import csv
import json

import pytest

from testbed.cli import main
from testbed.defense.config import PAPER_MODE


@pytest.fixture(scope="module")
def drive(tmp_path_factory):
    out = tmp_path_factory.mktemp("drive")
    assert main(["run", "parking-lot", "--localization", "msf", "--speed", "4", "--duration", "12", "--attack",
                 "trace:default,start=3", "--defense", "ld3", "--record", "--out", str(out)]) == 0
    return out


def test_replay_detects_when_the_closed_loop_run_did(drive, capsys):
    assert main(["replay", str(drive)]) == 0
    printed = capsys.readouterr().out
    closed_loop = json.loads((drive / "summary.json").read_text())["detection_time_s"]
    rows = list(csv.DictReader((drive / "replay" / "replay.csv").open()))
    alarm = next(float(r["t"]) for r in rows if r["mode"] == "ar")
    assert closed_loop is not None and abs(alarm - closed_loop) <= 0.05  # one detection period at 20 Hz
    assert f"ld3 detects at {closed_loop:.2f} s" in printed
    assert len(rows) > 150 and (drive / "replay" / "replay.png").is_file()
    after = [r for r in rows if float(r["t"]) > alarm]
    assert after and all(r["fused_dev"] != "" for r in after)  # the response's fusion runs as a shadow
    before = [r for r in rows if float(r["t"]) < 3.0]
    assert all(abs(float(r["msf_dev"]) - float(r["ld_dev"])) < 0.2 for r in before if r["ld_dev"])


def _setting(key: str, value: object) -> str:
    shown = str(value).lower() if isinstance(value, bool) else f'"{value}"' if isinstance(value, str) else value
    return f"defense.{key}={shown}"


@pytest.mark.parametrize("heading", [{}, {"heading": "fused", "heading_clamp": 0.05}], ids=["paper", "clamped"])
def test_a_paper_mode_drive_replays_to_the_same_detection(heading, tmp_path, capsys):
    """The recorded [defense] table holds heading_clamp and the fail-closed keys at their defaults, which paper
    mode (MSF heading, fail_closed = false) does not run: the replay rebuilds the run's settings from it."""
    settings = [arg for key, value in {**PAPER_MODE, **heading}.items() for arg in ("--set", _setting(key, value))]
    assert main(["run", "parking-lot", "--localization", "msf", "--speed", "4", "--duration", "12", "--attack",
                 "trace:default,start=3", "--defense", "ld3", *settings, "--record", "--out",
                 str(tmp_path / "d")]) == 0
    closed_loop = json.loads((tmp_path / "d" / "summary.json").read_text())
    assert closed_loop["defense_params"]["fail_closed"] is False and closed_loop["detection_time_s"] is not None
    capsys.readouterr()
    assert main(["replay", str(tmp_path / "d")]) == 0, capsys.readouterr().err
    rows = list(csv.DictReader((tmp_path / "d" / "replay" / "replay.csv").open()))
    alarm = next(float(r["t"]) for r in rows if r["mode"] == "ar")
    assert abs(alarm - closed_loop["detection_time_s"]) <= 0.05  # one detection period at 20 Hz
    assert f"ld3 detects at {closed_loop['detection_time_s']:.2f} s" in capsys.readouterr().out


def test_replay_takes_other_defense_parameters(drive, tmp_path, capsys):
    assert main(["replay", str(drive / "run.mcap"), "--set", "defense.tau=1000", "--out", str(tmp_path)]) == 0
    assert "ld3 never alarms" in capsys.readouterr().out


def test_replay_refuses_what_it_cannot_read(tmp_path, capsys):
    assert main(["replay", str(tmp_path / "missing.mcap")]) == 2
    assert "no recorded drive" in capsys.readouterr().err
    (tmp_path / "run.mcap").write_bytes(b"")
    assert main(["replay", str(tmp_path)]) == 2
    assert "give --track" in capsys.readouterr().err
