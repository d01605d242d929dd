"""`detector.weights` names the shipped checkpoint by its file name, or any checkpoint by path; a neural detector
that names none reads the shipped one, with traffic as without."""

import json
import re

import pytest

from testbed.eval.run.runner import run_scenario
from testbed.eval.run.scenario import Scenario, ScenarioError, load_scenario
from testbed.perception.detectors.weights import SHIPPED, resolve


def test_shipped_checkpoints_resolve_inside_the_package_and_other_values_are_paths(tmp_path):
    for name in SHIPPED:
        path = resolve(name)
        assert path.is_file() and path.name == name and path.parent.name == "weights"
    assert resolve(str(tmp_path / "mine.pt")) == tmp_path / "mine.pt"


def test_a_scenario_takes_a_shipped_name_and_refuses_a_missing_checkpoint_naming_the_shipped_ones():
    sc = Scenario.build(name="t", track="local", detector="neural", detector_params={"weights": "lanenet.pt"})
    assert sc.detector_params == {"weights": "lanenet.pt"} and SHIPPED == ("lanenet.pt",)
    with pytest.raises(ScenarioError, match=re.escape("no checkpoint at nope.pt: name a shipped one (lanenet.pt)")):
        Scenario.build(name="t", track="local", detector="neural", detector_params={"weights": "nope.pt"})
    with pytest.raises(ScenarioError, match=re.escape("no checkpoint at lanenet-traffic.pt")):
        Scenario.build(name="t", track="local", detector="neural", detector_params={"weights": "lanenet-traffic.pt"})


def test_with_traffic_a_neural_detector_that_names_no_weights_reads_the_shipped_weights():
    busy = {"name": "t", "track": "local", "detector": "neural", "traffic": {"vehicles": 6}}
    assert Scenario.build(**busy).run_detector_params == {}
    assert Scenario.build(**busy, detector_params={"tracking": False}).run_detector_params == {"tracking": False}
    assert Scenario.build(**{**busy, "detector": "neural-onnx"}).run_detector_params == {}
    named = Scenario.build(**busy, detector_params={"weights": "lanenet.pt"})
    assert named.run_detector_params == {"weights": "lanenet.pt"}  # a named checkpoint is kept
    assert Scenario.build(**{**busy, "detector": "oracle"}).run_detector_params == {}
    empty = Scenario.build(name="t", track="local", detector="neural")
    assert empty.run_detector_params == {} and empty.detector_params == {}


def test_a_run_in_traffic_records_that_its_detector_read_the_shipped_weights(tmp_path):
    sc = load_scenario("highway").replace(detector="neural", duration=0.2, traffic={"vehicles": 2})
    run_scenario(sc, tmp_path)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["resolved_scenario"]["detector_params"]["weights"] is None  # the shipped lanenet.pt
    assert summary["resolved_scenario"]["traffic"]["vehicles"] == 2
