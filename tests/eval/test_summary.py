"""summary.json's typed model: the consequence is an enum whose value is what the file holds, and a value
outside it is refused."""

import json

import pytest
from pydantic import ValidationError

from testbed.eval.run.consequence import Consequence
from testbed.eval.run.summary import RunSummary

FIELDS = {"package_version": None, "git_commit": None, "resolved_scenario": {}, "scenario": "s", "seed": 0,
          "track": "slr", "vehicle": "sedan", "attack": None, "threat_model": "none", "defense": "ld3",
          "condition": "day", "detector": "oracle", "localization": "truth", "sim_time_s": 1.0, "wall_time_s": 1.0,
          "real_time_factor": 1.0, "lane_width_m": 3.5, "lane_straddle_dev_m": 0.8, "max_abs_dev_m": 0.1,
          "final_dev_m": 0.0, "faults": [], "detected": False, "detection_time_s": None, "detection_dev_m": None,
          "ar_max_dev_m": None, "ar_stop_dev_m": None, "stop_time_s": None}


def test_the_consequence_is_an_enum_written_as_its_value(tmp_path):
    summary = RunSummary(**FIELDS, consequence="stop_in_lane")
    assert summary.consequence is Consequence.STOP_IN_LANE
    summary.write(tmp_path / "summary.json")
    text = (tmp_path / "summary.json").read_text()
    assert '"consequence": "stop_in_lane",' in text
    assert json.loads(text)["consequence"] == "stop_in_lane"


def test_a_consequence_outside_the_enum_is_refused():
    with pytest.raises(ValidationError, match="consequence"):
        RunSummary(**FIELDS, consequence="teleported")
