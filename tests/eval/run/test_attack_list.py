"""A scenario's attack as a list: loading, `--set attack.N.KEY`, the JSON Schema, and the TOML round trip."""

import jsonschema
import pytest

from testbed.eval.run.scenario import ScenarioError, add_attacks, apply_settings, load_scenario, scenario_from_dict
from testbed.eval.run.scenario_reference import json_schema
from testbed.eval.run.scenario_toml import scenario_document, write_scenario

DOC = {"track": "local", "localization": "msf", "defense": "ld3",
       "attack": [{"kind": "trace", "start": 12.0}, {"kind": "drp-trace", "start": 14.0, "shift": 0.5}]}


def test_a_list_of_attack_tables_loads_and_is_set_by_index():
    sc = scenario_from_dict(DOC, "two")
    assert [t["kind"] for t in sc.attack] == ["trace", "drp-trace"]
    changed = apply_settings(sc, ["attack.1.shift=0.9"])
    assert changed.attack[1]["shift"] == 0.9 and changed.attack[0] == sc.attack[0]
    with pytest.raises(ScenarioError, match=r"attack\.N\.KEY with N in 0\.\.1"):
        apply_settings(sc, ["attack.shift=0.9"])
    with pytest.raises(ScenarioError, match=r"attack\.N\.KEY"):
        apply_settings(sc, ["attack.2.shift=0.9"])
    with pytest.raises(ScenarioError, match="unknown attack kind"):
        scenario_from_dict({**DOC, "attack": [{"kind": "trace"}, {"kind": "teleport"}]}, "bad")
    with pytest.raises(ScenarioError, match="non-empty list"):
        scenario_from_dict({**DOC, "attack": []}, "empty")


def test_one_attack_takes_plain_keys_and_more_compose_after_it():
    sc = scenario_from_dict({**DOC, "attack": {"kind": "trace"}}, "one")
    assert apply_settings(sc, ["attack.start=3"]).attack == {"kind": "trace", "start": 3}
    assert add_attacks(sc, ["offmap:distance=20"]).attack == [{"kind": "trace"}, {"kind": "offmap", "distance": 20}]


def test_the_schema_accepts_a_list_and_refuses_an_unknown_member():
    schema = json_schema()
    jsonschema.validate(DOC, schema)
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate({**DOC, "attack": [{"kind": "teleport"}]}, schema)


def test_a_scenario_written_as_toml_loads_back_the_same(tmp_path):
    sc = apply_settings(scenario_from_dict(DOC, "two"), ["defense.b=0.6", "detector.kind=oracle",
                                                         "detector.noise_std=0.05", "seed=4"])
    write_scenario(tmp_path / "two.toml", sc, "a comment\non two lines")
    back = load_scenario(str(tmp_path / "two.toml"))
    assert scenario_document(back) == scenario_document(sc)
    text = (tmp_path / "two.toml").read_text()
    assert text.startswith("# a comment\n# on two lines\n")
    assert "fail_closed = true" in text and "window = 5" in text and "savior_b" not in text  # defaults written out
