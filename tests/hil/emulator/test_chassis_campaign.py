"""The chassis campaign over CAN: its runs, its table, and its registration through the `ld3.campaigns`
entry point (declared in pyproject.toml, so that testbed never imports hil)."""

import importlib
import tomllib
from pathlib import Path

from hil.emulator.campaigns import (
    AR_DECEL,
    CHASSIS,
    REPETITIONS,
    SETTINGS,
    SPEEDS,
    chassis_runs,
    chassis_table,
    run_over_can,
)
from testbed.eval.campaign.driver import CampaignRun
from testbed.eval.experiments.campaigns import CampaignSpec
from testbed.eval.run.scenario import load_scenario
from tests.eval.run.summary_helpers import fake_hil_summary

ROOT = Path(__file__).resolve().parents[3]


def test_chassis_runs_speeds_settings_and_repetitions():
    runs = chassis_runs("neural")
    assert len(runs) == len({r.run_id for r in runs}) == len(SPEEDS) * len(SETTINGS) * REPETITIONS == 24
    assert AR_DECEL < 3.0
    for r in runs:
        sc = r.scenario
        assert sc.track == "parking-lot" and sc.vehicle == "dev-chassis" and sc.speed == r.tags["speed"]
        assert sc.detector == "oracle" and sc.seed == r.tags["rep"]
        defense, params, attacked = SETTINGS[r.tags["setting"]]
        assert sc.defense == defense and sc.defense_params == params
        assert (sc.attack is not None) == attacked
    assert {r.scenario.defense_params.get("ar_decel") for r in runs if r.scenario.defense == "ld3"} == {AR_DECEL}
    assert {r.scenario.defense_params["max_decel"] for r in runs if r.scenario.defense == "ld3-naive-ar"} == {AR_DECEL}


def test_chassis_table_rows_per_speed_and_setting():
    sc = load_scenario("parking-lot")
    base = {"consequence": "stop_in_lane", "detected": True, "detection_dev_m": 0.1, "max_abs_dev_m": 0.4,
            "ar_max_dev_m": 0.4, "ar_stop_dev_m": -0.3, "final_dev_m": -0.3, "can_frames_tx": 10,
            "can_frames_rx": 30, "can_frames_rejected": 0}
    done = [(CampaignRun(f"4mps/ld3-rep{k}", sc, {"speed": 4.0, "setting": "ld3", "rep": k}),
             fake_hil_summary(**{**base, "ar_max_dev_m": 0.4 + 0.2 * k})) for k in range(2)]
    done.append((CampaignRun("4mps/none-rep0", sc, {"speed": 4.0, "setting": "none", "rep": 0}),
                 fake_hil_summary(**{**base, "detected": False, "detection_dev_m": None, "ar_max_dev_m": None,
                                     "ar_stop_dev_m": None, "max_abs_dev_m": 2.5, "final_dev_m": 2.4,
                                     "consequence": "out_of_lane"})))
    table = chassis_table(done, Path("."))
    assert "| 4 m/s | ld3 | 2 | 2/2 | 0.10, 0.00 | 0.50, 0.10 | 0.30, 0.00 | stop_in_lane ×2 | 20 / 60 / 0 |" in table
    assert "| 4 m/s | none | 1 | 0/1 | – | 2.50, 0.00 | 2.40, 0.00 | out_of_lane ×1 | 10 / 30 / 0 |" in table


def test_pyproject_registers_the_chassis_campaign_by_entry_point():
    declared = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["entry-points"]["ld3.campaigns"]
    module, _, attribute = declared["chassis"].partition(":")
    spec = getattr(importlib.import_module(module), attribute)
    assert spec is CHASSIS and isinstance(spec, CampaignSpec) and spec.name == "chassis"
    assert spec.execute is run_over_can and spec.build is chassis_runs


def test_testbed_never_imports_hil():
    offenders = [str(p.relative_to(ROOT)) for p in (ROOT / "testbed").rglob("*.py")
                 if any(line.startswith(("import hil", "from hil")) for line in p.read_text().splitlines())]
    assert offenders == []
