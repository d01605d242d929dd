"""`detector.weights` names a shipped checkpoint by its file name, or any checkpoint by path."""

import re

import pytest

from testbed.eval.scenario import Scenario, ScenarioError
from testbed.perception.weights import SHIPPED, resolve


def test_shipped_checkpoints_resolve_inside_the_package_and_other_values_are_paths(tmp_path):
    for name in SHIPPED:
        path = resolve(name)
        assert path.is_file() and path.name == name and path.parent.name == "weights"
    assert resolve(str(tmp_path / "mine.pt")) == tmp_path / "mine.pt"


def test_a_scenario_takes_a_shipped_name_and_refuses_a_missing_checkpoint_naming_the_shipped_ones():
    sc = Scenario.build(name="t", track="local", detector="neural", detector_params={"weights": "lanenet-traffic.pt"})
    assert sc.detector_params == {"weights": "lanenet-traffic.pt"}
    with pytest.raises(ScenarioError, match=re.escape("no checkpoint at nope.pt: name a shipped one (lanenet.pt, "
                                                      "lanenet-traffic.pt)")):
        Scenario.build(name="t", track="local", detector="neural", detector_params={"weights": "nope.pt"})
