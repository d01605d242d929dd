import numpy as np
import pytest
import torch

from testbed.errors import UserError
from testbed.perception.detectors.weights import resolve
from testbed.perception.lab import closed_loop
from testbed.perception.lab.closed_loop import (
    drive,
    drive_scenario,
    error_stats,
    markdown_table,
    run_closed_loop,
    write_report,
)
from testbed.perception.training.seeds import Cell, cells, check_cells
from testbed.rates import CONTROL_HZ


def test_cells_use_distinct_held_out_layouts_and_refuse_unknown_names():
    grid = cells(["local", "highway"], ["day", "rain"])
    assert [(c.preset, c.condition) for c in grid] == [("local", "day"), ("local", "rain"), ("highway", "day"),
                                                       ("highway", "rain")]
    assert len({c.track_seed for c in grid}) == 4 and all(c.track_seed >= 9000 for c in grid)
    with pytest.raises(ValueError, match="unknown preset 'moon'"):
        cells(["moon"], ["day"])
    with pytest.raises(ValueError, match="unknown condition 'fog'"):
        cells(["local"], ["fog"])


def test_the_check_layouts_drive_the_second_held_out_block(monkeypatch):
    driven = []
    monkeypatch.setattr(closed_loop, "drive", lambda cell, *args, **kwargs: driven.append(cell) or {"cell": cell})
    out = run_closed_loop(["slr", "local"], ["day", "worn"], check=True)
    assert driven == check_cells(["slr", "local"], ["day", "worn"]) and [r["cell"] for r in out] == driven
    assert not {c.track_seed for c in driven} & {c.track_seed for c in cells(["slr", "local"], ["day", "worn"])}


def test_a_drive_in_traffic_reads_the_shipped_weights_unless_told_otherwise():
    cell = Cell("urban-straight", "day", 9010)
    assert drive_scenario(cell, "neural", 30.0, traffic=6)[0].run_detector_params == {}
    assert drive_scenario(cell, "neural", 30.0)[0].run_detector_params == {}
    told = drive_scenario(cell, "neural", 30.0, traffic=6, weights="lanenet.pt")[0]
    assert told.run_detector_params == {"weights": "lanenet.pt"}
    assert drive_scenario(cell, "neural", 30.0, fit="near")[0].run_detector_params == {"fit": "near"}


def test_error_stats_ignore_ticks_without_a_deviation():
    s = error_stats(np.array([np.nan, 0.1, 0.3, 0.2]))
    assert s["mean_m"] == pytest.approx(0.2) and s["max_m"] == pytest.approx(0.3)
    assert error_stats(np.array([np.nan])) == {"mean_m": None, "p99_m": None, "max_m": None}


def _result(cond: str, raw: float, tracked: float) -> dict:
    return {"preset": "local", "condition": cond, "track": "local@9040", "speed_mps": 12.0, "sim_time_s": 30.0,
            "frames": 600, "detector": "neural", "weights": None, "raw": np.full(10, raw),
            "tracked": np.full(10, tracked)}


def test_tables_judge_the_tracked_errors_against_the_targets(tmp_path):
    results = [_result("day", 0.2, 0.04), _result("rain", 0.1, 0.09)]
    table = markdown_table(results)
    assert "| day | 0.200 | 0.200 | 0.200 | 0.040 | 0.040 | 0.040 | yes |" in table
    assert "| rain | 0.100 | 0.100 | 0.100 | 0.090 | 0.090 | 0.090 | no |" in table  # mean over 0.08
    assert table.startswith("Detector: neural (its default weights).")
    paths = write_report(results, tmp_path)
    csv = paths["csv"].read_text().splitlines()
    assert csv[0].startswith("preset,condition,track") and "tracked_p99_m" in csv[0] and len(csv) == 3


def test_traffic_drives_are_split_by_occlusion_in_their_own_table(tmp_path):
    busy = _result("day", 0.2, 0.05) | {"traffic": 6, "consequence": "reach_destination",
                                         "occluded": np.array([np.nan, 0.0, 0.3, 0.3, 0.3, 0.0, 0.0, 0.0, 0.0, 0.0])}
    busy["tracked"] = np.array([0.01, 0.01, 0.3, 0.3, 0.3, 0.01, 0.01, 0.01, 0.01, 0.01])
    table = markdown_table([busy])
    assert "| day | local | 6 | 12 | reach_destination | 0.30 | 0.300 | 0.300 | 0.300 | 0.300 | 0.010 | 0.010 " \
           "| 0.300 | no |" in table
    assert "| day | 0.30 | 0.300 | 0.300 | 0.010 | 0.010 | 0.300 | no |" in table
    assert "With traffic" not in markdown_table([_result("day", 0.2, 0.04)])
    csv = write_report([busy], tmp_path)["csv"].read_text().splitlines()
    assert "occluded_ticks" in csv[0] and "clear_p99_m" in csv[0] and "occluded\n" not in csv[0]


def test_bad_traffic_options_are_refused_before_any_drive():
    with pytest.raises(UserError, match="--traffic"):
        run_closed_loop(["slr"], ["day"], traffic=-1)
    with pytest.raises(UserError, match="--lead-gap places"):
        run_closed_loop(["slr"], ["day"], lead_gap=10.0)
    with pytest.raises(UserError, match="--lead-gap must"):
        run_closed_loop(["slr"], ["day"], traffic=6, lead_gap=0.0)


def test_weights_other_than_a_neural_detectors_checkpoint_are_refused_before_any_drive():
    with pytest.raises(UserError, match=r"--weights: .*no checkpoint at nowhere\.pt"):
        run_closed_loop(["slr"], ["day"], weights="nowhere.pt")
    with pytest.raises(UserError, match="--weights: "):
        run_closed_loop(["slr"], ["day"], detector="classical", weights="lanenet.pt")


def test_a_fit_other_than_a_neural_detectors_is_refused_before_any_drive():
    with pytest.raises(UserError, match="--fit: "):
        run_closed_loop(["slr"], ["day"], fit="spline")
    with pytest.raises(UserError, match="--fit: "):
        run_closed_loop(["slr"], ["day"], detector="classical", fit="near")


def test_settings_reach_every_drives_scenario_and_tracking_is_refused():
    cell = Cell("urban-straight", "day", 9010)
    told = drive_scenario(cell, "neural", 30.0, settings=("detector.track_at=[]",))[0]
    assert told.run_detector_params == {"track_at": []}
    with pytest.raises(UserError, match=r"detector\.tracking"):
        run_closed_loop(["slr"], ["day"], settings=("detector.tracking=false",))
    with pytest.raises(UserError, match="increasing distances"):
        run_closed_loop(["slr"], ["day"], settings=("detector.track_at=[8, 6]",))


@pytest.mark.slow
def test_a_drive_with_the_coefficients_tracker_scores_the_same_raw_detections_tracked_otherwise():
    cell = Cell("urban-straight", "day", 9010)
    ahead, coefficients = drive(cell, "neural", duration=2.0), drive(cell, "neural", duration=2.0,
                                                                     settings=("detector.track_at=[]",))
    np.testing.assert_array_equal(ahead["raw"], coefficients["raw"])
    assert not np.array_equal(ahead["tracked"], coefficients["tracked"], equal_nan=True)


@pytest.mark.slow
def test_a_drive_with_other_weights_scores_that_checkpoints_detections(tmp_path):
    cell = Cell("urban-straight", "day", 9010)
    state = torch.load(resolve("lanenet.pt"), map_location="cpu", weights_only=False)
    state["state_dict"] = {k: v * 0.9 if v.is_floating_point() else v for k, v in state["state_dict"].items()}
    torch.save(state, tmp_path / "scaled.pt")
    shipped, tuned = drive(cell, "neural", duration=2.0), drive(cell, "neural", duration=2.0,
                                                                 weights=str(tmp_path / "scaled.pt"))
    ticks = 2.0 * CONTROL_HZ
    assert np.isfinite(tuned["raw"]).sum() > 0.75 * ticks
    assert not np.array_equal(shipped["raw"], tuned["raw"], equal_nan=True)


@pytest.mark.slow
def test_a_drive_in_traffic_records_the_occlusion_of_every_tick():
    r = drive(Cell("urban-straight", "day", 9010), "neural", duration=3.0, traffic=6)
    assert r["consequence"] == "reach_destination" and r["traffic"] == 6 and r["weights"] is None
    assert "Detector: neural (its default weights)." in markdown_table([r])
    seen = r["occluded"][np.isfinite(r["occluded"])]
    ticks = 3.0 * CONTROL_HZ
    assert len(seen) > 0.93 * ticks and (seen > 0.0).all()  # the lead car 8 m ahead hides the far lines throughout
    assert np.isfinite(r["tracked"]).sum() > 0.83 * ticks


@pytest.mark.slow
def test_a_drive_scores_the_raw_and_the_tracked_detections_of_one_trajectory():
    r = drive(Cell("urban-straight", "day", 9010), "neural", duration=3.0)
    assert r["sim_time_s"] == pytest.approx(3.0) and r["frames"] == 60
    ticks = 3.0 * CONTROL_HZ
    assert np.isfinite(r["raw"]).sum() > 0.83 * ticks and np.isfinite(r["tracked"]).sum() > 0.83 * ticks
    assert not np.array_equal(r["raw"], r["tracked"])
