"""`ld3 bound`: the setting read from a scenario, the table it writes, and the bound beside a search's figures."""

from __future__ import annotations

import csv
import math

import pytest

from testbed.cli import main
from testbed.defense.config import PAPER_MODE
from testbed.errors import UserError
from testbed.eval.run.scenario import load_scenario
from testbed.eval.search.bound_table import RESIDUAL_STD, bound_rows, bound_setting, write_bound
from testbed.eval.search.report import search_bound, write_search_report
from tests.eval.search.search_helpers import toy_search


def test_the_setting_follows_the_scenario() -> None:
    sc = load_scenario("highway").replace(defense="ld3", defense_params={"heading_tau": 0.2})
    setting = bound_setting(sc)
    assert setting.every == 2 and setting.straddle_m == pytest.approx((3.75 - 1.90) / 2)
    assert (setting.lateral.b, setting.lateral.tau, setting.lateral.sigma) == (0.2, 2.0, RESIDUAL_STD["oracle"][0])
    assert (setting.heading.b, setting.heading.tau) == (0.03, 0.2)


def test_defenses_without_ld3_detection_are_refused() -> None:
    with pytest.raises(UserError, match="savior"):
        bound_setting(load_scenario("local").replace(defense="savior"))


def test_paper_mode_is_unbounded() -> None:
    sc = load_scenario("local").replace(defense="ld3", defense_params=dict(PAPER_MODE))
    (row,) = bound_rows(bound_setting(sc), [12.0])
    assert math.isinf(row.bound_m)


def test_a_tighter_heading_check_lowers_the_bound() -> None:
    base = load_scenario("highway").replace(defense="ld3")
    wide = {"steer_yaw_tol": 0.5}  # the yaw tolerance opened, so that the heading check's budget decides
    loose, tight = (bound_rows(bound_setting(base.replace(defense_params=p)), [27.0])[0]
                    for p in (wide, {**wide, "heading_b": 0.01, "heading_tau": 0.1}))
    assert tight.bound_m < loose.bound_m and tight.one_signed_m <= tight.bound_m + 1e-9


def test_the_yaw_tolerance_of_the_steered_pose_caps_the_heading_budget() -> None:
    base = load_scenario("highway").replace(defense="ld3")
    default, wide = (bound_rows(bound_setting(base.replace(defense_params=p)), [27.0])[0]
                     for p in ({}, {"steer_yaw_tol": 0.5}))
    assert default.bound_m < 0.8 * default.straddle_m < wide.bound_m


def test_write_bound_writes_the_table_once(tmp_path) -> None:
    rows = bound_rows(bound_setting(load_scenario("local").replace(defense="ld3")), [5.0, 12.0])
    table = write_bound(tmp_path / "b", rows, "local")
    assert "| 12 |" in table.read_text() and (tmp_path / "b" / "bound.png").stat().st_size
    with (tmp_path / "b" / "table.csv").open() as fh:
        assert [float(r["bound_m"]) for r in csv.DictReader(fh)] == pytest.approx([r.bound_m for r in rows], abs=1e-4)
    with pytest.raises(UserError, match="--force"):
        write_bound(tmp_path / "b", rows, "local")


def test_the_command_refuses_bad_input_in_one_line(capsys) -> None:
    assert main(["bound", "local", "--sigma", "0.1"]) == 2
    assert "--sigma" in capsys.readouterr().err
    assert main(["bound", "local", "--defense", "savior"]) == 2


def test_the_search_report_puts_the_bound_beside_the_search(tmp_path) -> None:
    search = toy_search(tmp_path / "s", budget=4)
    search.run()
    text = write_search_report(search).read_text()
    (row,) = bound_rows(bound_setting(search.spec.victim), [search.spec.victim.speed])
    assert "## Bound at the same settings" in text and f"{row.bound_m:.3f} m" in text
    solved_apart = search_bound(search.spec.victim)  # as `ld3 search` solves it while the trials run
    assert solved_apart == row and write_search_report(search, solved_apart).read_text() == text
    no_bound = search_bound(search.spec.victim.replace(defense="none"))
    assert isinstance(no_bound, str) and f"No bound: {no_bound}." in write_search_report(search, no_bound).read_text()
