"""The FusionRipper grid report: the markdown table and a success-rate heat map per track beside report.md."""

import matplotlib.image
import numpy as np

from testbed.eval.campaign.driver import CampaignRun
from testbed.eval.experiments.campaigns import GRID_D, GRID_F, fr_grid_table
from testbed.eval.run.consequence import ATTACK_GOAL_M
from testbed.eval.run.scenario import load_scenario
from tests.eval.run.summary_helpers import fake_summary


def fabricated_grid() -> list[tuple[CampaignRun, dict]]:
    """local: only d = 1.0, f = 1.5 succeeds (3 of 3 drives); highway: d = 0.3 never does; other cells empty."""
    sc = load_scenario("local")
    done = []
    for k in range(3):
        for d in GRID_D:
            for f in GRID_F:
                hit = d == 1.0 and f == 1.5
                tags = {"track": "local", "d": d, "f": f, "start": 8.0}
                done.append((CampaignRun(f"local-d{d:g}-f{f:g}-drive{k}", sc, tags),
                             fake_summary(max_abs_dev_m=ATTACK_GOAL_M["local"] + (0.2 if hit else -0.5),
                                          consequence="reach_destination", attack_state={"switch_time": 10.0})))
        for f in GRID_F:
            tags = {"track": "highway", "d": 0.3, "f": f, "start": 8.0}
            done.append((CampaignRun(f"highway-d0.3-f{f:g}-drive{k}", sc, tags),
                         fake_summary(max_abs_dev_m=0.1, consequence="reach_destination", attack_state=None)))
    return done


def test_grid_table_writes_the_heat_map_beside_the_report(tmp_path):
    markdown = fr_grid_table(fabricated_grid(), tmp_path)
    assert "| 1 | 0% (3); give-way 2.0–2.0 s | 0% (3); give-way 2.0–2.0 s | 0% (3); give-way 2.0–2.0 s | " \
           "100% (3); give-way 2.0–2.0 s |" in markdown
    assert "![success rate per d × f cell](fusionripper_grid.png)" in markdown
    png = matplotlib.image.imread(tmp_path / "fusionripper_grid.png")
    assert png.shape[0] > 300 and png.shape[1] > 600
    rgb = png[..., :3]
    yellow = (rgb[..., 0] > 0.9) & (rgb[..., 1] > 0.85) & (rgb[..., 2] < 0.25)  # viridis at 100 %
    purple = (rgb[..., 0] > 0.2) & (rgb[..., 0] < 0.32) & (rgb[..., 1] < 0.05) & (rgb[..., 2] > 0.3)  # at 0 %
    grey = np.all(np.abs(rgb - 0.85) < 0.01, axis=-1)  # cells without drives
    assert yellow.sum() > 500 and purple.sum() > 500 and grey.sum() > 500
