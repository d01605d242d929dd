"""summary.json's typed model: the consequence is an enum whose value is what the file holds, and a value
outside it is refused."""

import json

import pytest
from pydantic import ValidationError

from testbed.errors import UserError
from testbed.eval.run.consequence import Consequence
from testbed.eval.run.summary import HilSummary, RunSummary, read_summary
from tests.eval.run.summary_helpers import fake_hil_summary, fake_summary

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


def test_a_summary_reads_back_typed_as_it_was_written(tmp_path):
    written = fake_summary(consequence="hit_curb", max_abs_dev_m=float("nan"))
    written.write(tmp_path / "summary.json")
    read = read_summary(tmp_path / "summary.json")
    assert type(read) is RunSummary and read.consequence is Consequence.HIT_CURB and read.max_abs_dev_m is None
    assert read.model_dump(exclude={"max_abs_dev_m"}) == written.model_dump(exclude={"max_abs_dev_m"})
    fake_hil_summary(can_frames_tx=7).write(tmp_path / "hil.json")
    assert isinstance(hil := read_summary(tmp_path / "hil.json"), HilSummary) and hil.can_frames_tx == 7
    assert hil.consequence_basis == "plant"  # a basis other than a vehicle's "estimated" is a run over CAN


@pytest.mark.parametrize(("change", "named"), [
    (lambda d: d.pop("detected"), "detected"), (lambda d: d.update(max_abs_dev_m="far"), "max_abs_dev_m"),
    (lambda d: d.update(schema_version_of_old="x"), "schema_version_of_old"),
    (lambda d: d.update(consequence="teleported"), "consequence")])
def test_a_summary_not_of_this_version_is_one_line_naming_the_file_and_the_field(tmp_path, change, named):
    data = fake_summary().model_dump(mode="json")
    change(data)
    (tmp_path / "summary.json").write_text(json.dumps(data))
    with pytest.raises(UserError, match=named) as err:
        read_summary(tmp_path / "summary.json")
    assert str(tmp_path / "summary.json") in str(err.value) and "\n" not in str(err.value)


def test_a_non_finite_number_in_a_summary_is_refused(tmp_path):
    (tmp_path / "summary.json").write_text(json.dumps(fake_summary().model_dump(mode="json")).replace(
        '"max_abs_dev_m": 0.1', '"max_abs_dev_m": NaN'))
    with pytest.raises(UserError, match="NaN"):
        read_summary(tmp_path / "summary.json")
