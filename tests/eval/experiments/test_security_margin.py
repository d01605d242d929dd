"""The security-margin table assembled from toy searches (no simulation): cells, pooling, resuming, refusals."""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any

import pytest

from testbed.errors import UserError
from testbed.eval.campaign.driver import CampaignRun
from testbed.eval.experiments.security_margin import ROADS, cell_bound, cell_bound_on_car, plan_cells, security_margin
from tests.eval.search.search_helpers import toy_executor


class Counting:
    """The toy executor, counting the runs it makes."""

    def __init__(self) -> None:
        self.runs = 0

    def __call__(self, run: CampaignRun, run_dir: Path) -> dict[str, Any]:
        self.runs += 1
        return toy_executor(run, run_dir)


def _table(out: Path) -> list[dict[str, str]]:
    with (out / "table.csv").open() as fh:
        return list(csv.DictReader(fh))


def _trials(out: Path) -> list[dict[str, str]]:
    rows = []
    for path in sorted(out.glob("*/*/*/seed*/search/trials.csv")):
        with path.open() as fh:
            rows += [{**r, "cell": path.parts[len(out.parts):len(out.parts) + 3]} for r in csv.DictReader(fh)]
    return rows


def test_every_preset_and_two_held_out_layouts_by_default() -> None:
    cells = plan_cells()
    assert len(ROADS) == 9 and {c.road for c in cells} == set(ROADS)
    assert len(cells) == 9 * 4 * 4 * 3 and all(c.budget == 120 for c in cells)
    assert cells[0].victim().detector == "oracle" and plan_cells(roads=["highway@101"])[0].victim().track == \
        "highway@101"


@pytest.mark.parametrize("kwargs", [{"roads": ["nowhere"]}, {"defenses": ["ld4"]}, {"threats": ["telepathy"]},
                                    {"budget": 0}, {"seeds": [-1]}])
def test_unknown_names_are_refused(kwargs: dict[str, Any]) -> None:
    with pytest.raises(UserError):
        plan_cells(**kwargs)


def test_the_table_pools_the_seeds_and_resumes(tmp_path: Path) -> None:
    cells = plan_cells(roads=["local"], defenses=["ld3", "savior"], threats=["msf-output", "msf-output,ld-output"],
                       seeds=[0, 1], budget=4)
    execute = Counting()
    table = security_margin(cells, tmp_path, execute=execute, bound=lambda cell: 0.5,
                            car_bound=lambda cell, cache: 0.4, workers=1, progress=False)
    assert execute.runs == 8 * 4
    rows = _table(tmp_path)
    assert [(r["defense"], r["threat"]) for r in rows] == [("LD3 default", "msf-output"),
                                                          ("LD3 default", "msf-output,ld-output"),
                                                          ("SAVIOR", "msf-output"), ("SAVIOR", "msf-output,ld-output")]
    trials = _trials(tmp_path)
    for r in rows:
        mine = [t for t in trials if t["cell"] == ("local", "ld3" if r["defense"] == "LD3 default" else "savior",
                                                  r["threat"].replace(",", "+"))]
        assert int(r["trials"]) == len(mine) == 8
        assert int(r["losses"]) == sum(t["loss"] == "true" for t in mine)
        assert float(r["worst_max_dev_m"]) == pytest.approx(max(float(t["max_abs_dev_m"]) for t in mine), abs=1e-4)
        assert r["in_threat_model"] == str(r["threat"] == "msf-output").lower()
    assert {float(r["bound_m"]) for r in rows} == {0.5} and {float(r["bound_on_car_m"]) for r in rows} == {0.4}
    text = table.read_text()
    assert text.index("| local | LD3 default | msf-output |") < text.index("outside LD3's threat model") < \
        text.index("| local | LD3 default | msf-output,ld-output |")
    security_margin(cells, tmp_path, execute=execute, bound=lambda cell: 0.5,
                    car_bound=lambda cell, cache: 0.4, workers=1, progress=False)
    assert execute.runs == 8 * 4
    more = plan_cells(roads=["local"], defenses=["ld3"], threats=["msf-output"], seeds=[0], budget=6)
    security_margin(more, tmp_path, execute=execute, bound=lambda cell: 0.5,
                    car_bound=lambda cell, cache: 0.4, workers=1, progress=False)
    assert execute.runs == 8 * 4 + 2


def test_the_bound_column() -> None:
    savior, paper, default = plan_cells(roads=["local"], defenses=["savior", "ld3-paper", "ld3"], threats=["gnss"],
                                        seeds=[0])
    assert cell_bound(savior) is None and cell_bound(paper) == float("inf") and 0.2 < cell_bound(default) < 1.0


def test_the_lines_attacker_alone_is_in_the_table_without_a_bound(tmp_path: Path) -> None:
    (lines,) = plan_cells(roads=["local"], defenses=["ld3"], threats=["ld-output"], seeds=[0])
    assert {c.threat for c in plan_cells(roads=["local"], defenses=["ld3"], seeds=[0])} == {
        "gnss", "msf-output", "ld-output", "msf-output,ld-output"}
    assert cell_bound(lines) is None and cell_bound_on_car(lines, tmp_path) is None
    table = security_margin([lines], tmp_path, execute=toy_executor, workers=1, progress=False).read_text()
    assert "| local | LD3 default | ld-output | 1 × 120 |" in table.split("## Beside")[0]


def test_the_bound_on_the_car_is_kept_and_read_back(tmp_path: Path) -> None:
    savior, paper = plan_cells(roads=["local"], defenses=["savior", "ld3-paper"], threats=["gnss"], seeds=[0])
    assert cell_bound_on_car(savior, tmp_path) is None and cell_bound_on_car(paper, tmp_path) == float("inf")
    assert cell_bound_on_car(paper, tmp_path) == float("inf")  # read back from the file it kept
    assert json.loads((tmp_path / "local-ld3-paper.json").read_text())["bound_on_car_m"] == "inf"
