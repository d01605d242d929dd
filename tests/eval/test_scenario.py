"""Scenario files: shipped ones load, overrides validate, bad input gives a ScenarioError with one line."""

import pytest

from testbed.eval.scenario import ScenarioError, apply_settings, load_scenario, shipped_scenarios

PRESETS = ("slr", "urban-straight", "urban-curvy", "highway", "local", "parking-lot")


def test_one_shipped_scenario_per_preset():
    names = shipped_scenarios()
    for preset in PRESETS:
        assert preset in names
        assert load_scenario(preset).track == preset


def test_overrides_replace_fields_and_validate():
    sc = load_scenario("urban-straight").with_overrides(speed=20.0, seed=3, defense="ld3")
    assert (sc.speed, sc.seed, sc.defense) == (20.0, 3, "ld3")
    with pytest.raises(ScenarioError, match="speed"):
        sc.with_overrides(speed=-1.0)
    with pytest.raises(ScenarioError, match="defense"):
        sc.with_overrides(defense="magic")


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("track = ", "malformed TOML"),
        ('speed = 3.0\n', "'track' is required"),
        ('track = "slr"\nwheels = 3\n', "unknown keys"),
        ('track = "slr"\nspeed = "fast"\n', "wrong type"),
    ],
)
def test_bad_files_raise_one_line_errors(tmp_path, text, message):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ScenarioError, match=message) as info:
        load_scenario(str(path))
    assert "\n" not in str(info.value)


def test_unknown_name_lists_shipped_scenarios():
    with pytest.raises(ScenarioError, match="urban-straight"):
        load_scenario("no-such-scenario")


def test_defense_table_carries_parameters(tmp_path):
    path = tmp_path / "d.toml"
    path.write_text('track = "slr"\n[defense]\nkind = "ld3"\nb = 0.5\ntau = 0.2\n')
    sc = load_scenario(str(path))
    assert sc.defense == "ld3"
    assert sc.defense_params == {"b": 0.5, "tau": 0.2}


def test_set_overrides_defense_attack_and_top_level_keys():
    sc = load_scenario("local").with_overrides(attack={"kind": "fusionripper", "d": 0.5})
    out = apply_settings(sc, ["defense.b=0.45", "defense.heading=msf", 'defense.kind="ld3"', "attack.start=12",
                              "speed=10"])
    assert out.defense == "ld3" and out.defense_params == {"b": 0.45, "heading": "msf"}
    assert out.attack == {"kind": "fusionripper", "d": 0.5, "start": 12} and out.speed == 10


@pytest.mark.parametrize(("item", "message"), [
    ("defense.b", "expected KEY=VALUE"),
    ("colour=red", "unknown scenario key"),
    ("camera.fov=40", "unknown section"),
    ("attack.start=3", "no attack"),
    ("speed=-1", "speed must be > 0"),
])
def test_set_refuses_what_it_cannot_apply(item, message):
    with pytest.raises(ScenarioError, match=message):
        apply_settings(load_scenario("slr"), [item])
