"""The scenario reference and JSON Schema come from the registries: shipped scenarios validate against the
schema, and what the loader refuses the schema refuses too."""

import tomllib
from importlib import resources

import jsonschema
import pytest

from testbed.eval.run.scenario import shipped_scenarios
from testbed.eval.run.scenario_reference import json_schema, reference_markdown


@pytest.fixture(scope="module")
def validator():
    schema = json_schema()
    jsonschema.Draft202012Validator.check_schema(schema)
    return jsonschema.Draft202012Validator(schema)


def test_every_shipped_scenario_validates_against_the_schema(validator):
    for name in shipped_scenarios():
        text = (resources.files("testbed.eval.run") / "scenarios" / f"{name}.toml").read_text()
        validator.validate(tomllib.loads(text))


@pytest.mark.parametrize("bad", [
    {"track": "moon"},
    {"track": "local", "speeed": 3.0},
    {"track": "local", "defense": {"kind": "ld3", "b": "high"}},
    {"track": "local", "defense": {"kind": "ld3", "lam": 1.5}},
    {"track": "local", "detector": {"kind": "oracle", "noise": 0.1}},
    {"track": "local", "attack": {"kind": "fusionripper", "d": "far"}},
    {"track": "local", "attack": {"kind": "drp-patch"}},
    {"track": "local", "rates": {"control_hz": 0}},
    {"track": "local", "rates": {"control_hertz": 50}},
    {"track": "local", "traffic": {"vehicles": -1}},
    {"track": "local", "traffic": {"vehicles": 2, "cars": 3}},
    {"track": "local", "traffic": {"vehicles": 2, "vehicle": "bus"}},
    {"track": "local", "traffic": {"vehicles": 2, "gap_spread": 1.0}},
    {"track": "local", "control": {"steer_rate_weight": -0.1}},
    {"track": "local", "control": {"rate_weight": 0.1}},
    {"track": "local", "speed": 0},
    {"track": "local", "seed": 1.5},
    {"track": "local", "name": "../escape"},
])
def test_the_schema_refuses_what_the_loader_refuses(validator, bad):
    assert not validator.is_valid(bad)


def test_the_reference_names_every_key_with_its_default():
    text = reference_markdown()
    for needle in ("| `heading` |", "`'fused'`", "| `noise_std` |", "[attack]` with kind = `drp-patch`",
                   "| `stop_decel` | float | `4.0` |", "| `headway` | float | `1.5` |"):
        assert needle in text
