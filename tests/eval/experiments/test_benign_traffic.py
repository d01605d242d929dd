import numpy as np

from testbed.conditions import CONDITIONS
from testbed.eval.experiments.campaigns import BENIGN_TRAFFIC_PRESETS, CAMPAIGNS, benign_traffic_table, selected_runs
from testbed.eval.run.outputs import TRAJECTORY_COLUMNS
from testbed.perception.lab.traffic_drive import LEAD_GAP_M
from testbed.traffic.fleet import Fleet
from tests.eval.run.summary_helpers import fake_summary
from tracks.presets import load_track
from vehicles.params import get_vehicle


def test_benign_traffic_drives_every_preset_and_condition_with_six_cars_at_the_egos_speed():
    runs = selected_runs("benign-traffic", "neural")
    assert "benign-traffic" in CAMPAIGNS.names() and len(runs) == len(BENIGN_TRAFFIC_PRESETS) * len(CONDITIONS) * 3
    assert {(r.tags["track"], r.tags["condition"]) for r in runs} == {(p, c) for p in BENIGN_TRAFFIC_PRESETS
                                                                       for c in CONDITIONS}
    for run in runs[::3]:
        sc = run.scenario
        assert (sc.defense, sc.localization, sc.detector) == ("ld3", "msf", "neural")
        assert sc.traffic.vehicles >= 6 and sc.traffic.speed == sc.speed and sc.traffic.ahead == LEAD_GAP_M
        assert sc.traffic.start_speed == 0.0  # started at rest with the ego: the lead car stays close
        track, sedan, ego = load_track(sc.track), get_vehicle("sedan"), get_vehicle(sc.vehicle)
        fleet = Fleet.place(sc.traffic, track, track.ego_lane, sc.start_s, sc.speed, np.random.default_rng(sc.seed),
                            (sedan.length, sedan.width), (ego.length, ego.width), track.length - 30.0)
        assert len(fleet.cars) == sc.traffic.vehicles


def test_benign_traffic_table_pools_the_tracked_errors_and_counts_alarms(tmp_path):
    runs = [r for r in selected_runs("benign-traffic", "neural") if r.run_id.startswith("local-rain-")]
    done = []
    for run, (alarm, err) in zip(runs, ((False, 0.05), (True, 0.1), (False, 0.3)), strict=True):
        run_dir = tmp_path / run.run_id
        run_dir.mkdir()
        rows = [",".join(TRAJECTORY_COLUMNS)]
        for ld in (0.2, 0.2 + err, np.nan):
            values = {c: "0" for c in TRAJECTORY_COLUMNS} | {"phys_dev": "0.2", "ld_dev": "" if np.isnan(ld) else
                                                             str(ld)}
            rows.append(",".join(values[c] for c in TRAJECTORY_COLUMNS))
        (run_dir / "trajectory.csv").write_text("\n".join(rows) + "\n")
        done.append((run, fake_summary(detected=alarm, max_abs_dev_m=0.1, consequence="reach_destination")))
    table = benign_traffic_table(done, tmp_path)
    cells = [c.strip() for c in next(line for line in table.splitlines() if line.startswith("| local")).split("|")]
    assert cells[2:7] == ["rain", "3", "6", "12.00", "1"]
    assert cells[7] == f"{np.mean([0, 0.05, 0, 0.1, 0, 0.3]):.3f}"
    assert cells[8] == f"{np.percentile([0, 0.05, 0, 0.1, 0, 0.3], 99):.3f}"
    assert cells[10] == "reach_destination ×3"
    assert "3 runs, 1 false alarms" in table
