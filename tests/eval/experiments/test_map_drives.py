"""`ld3 campaign maps`: per OpenDRIVE file its default route, benign with the oracle and the lane detector and
once attacked; refused files and bad --maps are one line; a table per file."""

from __future__ import annotations

import math

import pytest

from testbed.errors import UserError
from testbed.eval.experiments.campaigns import selected_runs
from testbed.eval.experiments.map_drives import CRUISE, _stopped_at, attack_start_s, attacked_route_m, map_table
from tests.eval.run.summary_helpers import fake_summary
from tests.tracks.opendrive.xodr_text import constant, document, geometry, road, section


def _maps(tmp_path):
    folder = tmp_path / "maps"
    folder.mkdir()
    lanes = [section(0.0, [constant(3.5)], [constant(3.5)])]
    (folder / "a.xodr").write_text(document(road("1", 300.0, [geometry(0, 0.0, 0.0, 0.0, 300.0, "<line/>")], lanes)))
    (folder / "bad.xodr").write_text("not xml")
    return folder


def test_each_file_gets_benign_drives_and_an_attacked_one_and_a_refused_file_none(tmp_path, capsys):
    runs = selected_runs("maps", "neural", maps=[str(_maps(tmp_path))])
    assert [r.run_id for r in runs] == ["a-benign-oracle", "a-benign-neural", "a-attacked-neural"]
    assert "bad.xodr: file: not XML" in capsys.readouterr().err
    for run in runs:
        sc = run.scenario
        assert sc.track == f"xodr:{tmp_path / 'maps' / 'a.xodr'}" and sc.speed == CRUISE and sc.defense == "ld3"
        assert sc.duration >= 300.0 / CRUISE
    assert runs[0].scenario.attack is None and runs[2].scenario.attack is not None
    assert [r.run_id for r in selected_runs("maps", "oracle", maps=[str(tmp_path / "maps" / "a.xodr")])] == [
        "a-benign-oracle", "a-attacked-oracle"]


@pytest.mark.parametrize(("name", "maps", "message"), [
    ("maps", [], "add --maps"),
    ("table4", ["x.xodr"], "--maps names the OpenDRIVE files"),
    ("maps", ["nowhere.xodr"], "--maps nowhere.xodr: no such file or folder"),
])
def test_maps_are_needed_by_the_maps_campaign_only(name, maps, message, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(UserError, match=message):
        selected_runs(name, "neural", maps=maps)


def test_the_table_has_one_section_per_file_and_judges_each_drive(tmp_path):
    runs = selected_runs("maps", "neural", maps=[str(_maps(tmp_path))])
    base = {"max_abs_dev_m": 0.1, "sim_time_s": 30.0, "detection_time_s": None, "detected": False}
    sums = [fake_summary(**dict(base, consequence="reach_destination")),
            fake_summary(**dict(base, consequence="stop_in_lane", detected=True, detection_time_s=12.5,
                                alarm_check="heading-lines")),
            fake_summary(**dict(base, consequence="stop_in_lane", detected=True, detection_time_s=11.0))]
    table = map_table(list(zip(runs, sums, strict=True)), tmp_path)
    assert "### a.xodr (default route, 300 m)" in table
    rows = [line for line in table.splitlines() if line.startswith("| benign") or line.startswith("| attacked")]
    assert rows[0].endswith("| yes |") and rows[1].endswith("| NO |") and rows[2].endswith("| yes |")
    assert "12.50 s, heading-lines |" in rows[1]
    alarmed_early = sums[2].model_copy(update={"detection_time_s": 8.0})  # the attack starts at 10 s
    early = map_table([(runs[2], alarmed_early)], tmp_path)
    assert "8.00 s (before the attack)" in early and early.endswith("| NO |")


def test_a_route_too_short_to_detect_and_stop_gets_no_attacked_drive_and_says_what_it_needs(tmp_path):
    folder = tmp_path / "short"
    folder.mkdir()
    lanes = [section(0.0, [constant(3.5)])]
    (folder / "s.xodr").write_text(document(road("1", 93.0, [geometry(0, 0.0, 0.0, 0.0, 93.0, "<line/>")], lanes)))
    runs = selected_runs("maps", "neural", maps=[str(folder)])
    needs = math.ceil(attacked_route_m(runs[0].scenario.start_s))
    assert [r.run_id for r in runs] == ["s-benign-oracle", "s-benign-neural"] and needs > 93
    base = fake_summary(max_abs_dev_m=0.1, sim_time_s=16.0, detection_time_s=None, detected=False,
                        consequence="reach_destination")
    table = map_table([(run, base) for run in runs], tmp_path)
    assert table.splitlines()[-1] == (f"| attacked | neural | too short for an attacked drive at {CRUISE:g} m/s: "
                                      f"needs {needs} m | | | | not judged |")
    assert table.count("| yes |") == 2 and "| NO |" not in table


def test_the_length_an_attacked_drive_needs_holds_the_detection_and_the_stop():
    needs = attacked_route_m(20.0)
    assert _stopped_at(attack_start_s(needs), 20.0) <= needs + 0.01
    assert _stopped_at(attack_start_s(needs - 5.0), 20.0) > needs - 5.0  # 5 m shorter does not hold them
    long = 300.0  # the attack at ATTACK_AT, alarmed at 16.1 s: 20 + 112.5 + 15·1.1 + 28.1 + 30 m
    assert _stopped_at(attack_start_s(long), 20.0) == pytest.approx(20 + 112.5 + 16.5 + 225 / 8 + 30)
