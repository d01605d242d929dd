"""Figures on demand: a run that defers them writes every other output to the same bytes and believed.csv;
`ld3 figures` then draws birdseye.png (and ar_fusion.png after an attack response) from the folder."""

import json
from pathlib import Path

import cv2

from testbed.cli import main
from testbed.defense.config import PAPER_MODE
from testbed.eval.run.figures import BELIEVED, read_believed, read_rows
from testbed.eval.run.runner import run_into
from testbed.eval.run.scenario import load_scenario

FR = {"kind": "fusionripper", "d": 1.0, "f": 1.5, "start": 8.0}


def _files(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in folder.iterdir()}


def test_deferred_figures_are_drawn_later_from_the_folder(tmp_path, capsys):
    sc = load_scenario("local").with_overrides(duration=20.0, detector="oracle", localization="msf", defense="ld3",
                                               attack=FR)
    now, later = tmp_path / "now", tmp_path / "campaign" / "later"
    now.mkdir()
    later.mkdir(parents=True)
    result = run_into(sc, now)
    run_into(sc, later, figures=False)
    drawn, deferred = _files(now), _files(later)
    assert {"birdseye.png", "ar_fusion.png"} <= set(drawn) and not {"birdseye.png", "ar_fusion.png"} & set(deferred)
    assert set(deferred) - set(drawn) == {BELIEVED}
    assert all(deferred[name] == data for name, data in drawn.items() if name.endswith(".csv"))
    timed = ("wall_time_s", "real_time_factor")
    assert ({k: v for k, v in json.loads(deferred["summary.json"]).items() if k not in timed}
            == {k: v for k, v in json.loads(drawn["summary.json"]).items() if k not in timed})
    believed = read_believed(later / BELIEVED)
    assert believed.shape == result.believed_xy.shape and abs(believed - result.believed_xy).max() < 1e-6
    rows = read_rows(later)
    assert [(r.t, r.mode, r.fused_dev is None) for r in rows] == [
        (round(r.t, 6), r.mode, r.fused_dev is None) for r in result.rows]

    assert main(["figures", str(tmp_path / "campaign")]) == 0
    assert "drawn for 1 of 1 run folders" in capsys.readouterr().out
    for name in ("birdseye.png", "ar_fusion.png"):
        a, b = cv2.imread(str(now / name)), cv2.imread(str(later / name))
        assert a.shape == b.shape and (a != b).any(axis=2).mean() < 0.01, name  # trajectory.csv's rounding only
    assert main(["figures", str(later)]) == 0  # drawn already: nothing to draw
    assert "drawn for 0 of 1" in capsys.readouterr().out


def test_ld3_campaign_figures_later_runs_the_executor_without_figures(tmp_path, monkeypatch):
    from testbed.eval.campaign.driver import run_and_write, run_and_write_data
    from testbed.eval.experiments import campaigns

    seen = []
    monkeypatch.setattr(campaigns, "run_campaign", lambda runs, out, **kwargs: seen.append(kwargs["execute"]) or [])
    argv = ["campaign", "table4", "--runs", "ld3-start6", "--out", str(tmp_path), "--workers", "1"]
    assert main([*argv, "--figures-later"]) == 0 and main(argv) == 0
    assert seen == [run_and_write_data, run_and_write]


def test_a_paper_mode_run_has_its_figures_drawn_later(tmp_path, capsys):
    """summary.json records heading_clamp and the fail-closed keys, which paper mode does not run: `ld3 figures`
    rebuilds the scenario without them."""
    sc = load_scenario("parking-lot").with_overrides(duration=4.0, detector="oracle", localization="msf",
                                                     defense="ld3", defense_params=PAPER_MODE)
    (tmp_path / "run").mkdir()
    run_into(sc, tmp_path / "run", figures=False)
    assert main(["figures", str(tmp_path / "run")]) == 0, capsys.readouterr().err
    assert (tmp_path / "run" / "birdseye.png").is_file()
