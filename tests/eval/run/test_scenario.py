"""Scenario files: shipped ones load, overrides validate, bad input gives a ScenarioError with one line."""

import pytest

from testbed.eval.run.scenario import ScenarioError, apply_settings, check_needs, load_scenario, shipped_scenarios
from testbed.eval.run.scenario_toml import write_scenario

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
        ('track = "slr"\nspeed = "fast"\n', "scenario bad: speed must be a number, got 'fast'"),
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


def test_control_table_is_set_validated_and_written_back(tmp_path):
    sc = apply_settings(load_scenario("slr"), ["control.steer_rate_weight=0.1"])
    assert sc.control.steer_rate_weight == 0.1 and load_scenario("slr").control.steer_rate_weight == 0.03
    write_scenario(tmp_path / "rate.toml", sc)
    assert load_scenario(str(tmp_path / "rate.toml")).control == sc.control
    with pytest.raises(ScenarioError, match=r"control.steer_rate_weight must be >= 0"):
        apply_settings(sc, ["control.steer_rate_weight=-1"])
    with pytest.raises(ScenarioError, match=r"unknown scenario key 'control.rate'; known in \[control\]: "
                                            r"lateral_accel, steer_lat_accel, steer_rate_weight"):
        apply_settings(sc, ["control.rate=1"])
    assert apply_settings(sc, ["control.lateral_accel=2.5"]).control.lateral_accel == 2.5
    with pytest.raises(ScenarioError, match=r"control.lateral_accel must be > 0"):
        apply_settings(sc, ["control.lateral_accel=0"])


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


@pytest.mark.parametrize(("defense", "params", "message"), [
    ("savior", {"b": 0.45}, r"\[defense\] b: not read by defense 'savior'.*savior_b"),
    ("none", {"heading": "msf"}, r"not read by defense 'none'.*reads no \[defense\] keys"),
    ("ld3-naive-ar", {"window": 20}, r"window: not read by defense 'ld3-naive-ar'"),
])
def test_defense_parameters_the_defense_does_not_read_are_refused(defense, params, message):
    sc = load_scenario("local")
    with pytest.raises(ScenarioError, match=message):
        sc.with_overrides(defense=defense, localization="msf", defense_params=params)


def test_defense_parameters_it_reads_and_the_loops_existence_threshold_are_accepted():
    sc = load_scenario("local")
    assert sc.with_overrides(defense="savior", localization="msf", defense_params={"savior_b": 2.0}).defense == "savior"
    assert sc.with_overrides(defense_params={"existence_threshold": 0.6}).defense == "none"


def test_detector_table_and_set_carry_the_detectors_parameters(tmp_path):
    f = tmp_path / "d.toml"
    f.write_text('track = "local"\n[detector]\nkind = "oracle"\nnoise_std = 0.05\n')
    sc = load_scenario(str(f))
    assert (sc.detector, sc.detector_params) == ("oracle", {"noise_std": 0.05})
    sc = apply_settings(sc, ["detector.dropout=0.1"])
    assert sc.detector_params == {"noise_std": 0.05, "dropout": 0.1}


@pytest.mark.parametrize(("item", "message"), [
    ("detector.noise_std=-1", r"\[detector oracle\] 'noise_std' must be >= 0"),
    ("detector.gain=2", r"\[detector oracle\] unknown parameter 'gain'; known: noise_std, dropout"),
    ("attack.d=far", r"\[attack fusionripper\] 'd' must be a number"),
    ("track=moon", r"unknown track preset 'moon'; known: slr, urban-straight"),
    ("vehicle=tank", r"unknown vehicle 'tank'; known: sedan, dev-chassis"),
])
def test_component_parameters_are_validated_when_the_scenario_is(item, message):
    sc = load_scenario("local").with_overrides(localization="msf", attack={"kind": "fusionripper"})
    with pytest.raises(ScenarioError, match=message):
        apply_settings(sc, [item])


def test_neural_weights_must_exist(tmp_path):
    with pytest.raises(ScenarioError, match=r"no checkpoint at .*missing\.pt: name a shipped one \(lanenet\.pt\), "
                                            r"train one with `ld3 ld train`"):
        apply_settings(load_scenario("local"), ["detector.kind=neural", f"detector.weights={tmp_path}/missing.pt"])


def test_a_lane_detection_attack_nothing_steers_by_is_named_not_silent(caplog):
    base = load_scenario("slr").replace(detector="oracle", attack={"kind": "drp-trace", "start": 0.0})
    with caplog.at_level("WARNING", logger="testbed.eval.run.scenario"):
        check_needs(base)
    assert "changes only the recorded D_LD" in caplog.text and "'none'" in caplog.text
    caplog.clear()
    with caplog.at_level("WARNING", logger="testbed.eval.run.scenario"):
        check_needs(base.replace(defense="ld3", localization="msf"))
    assert caplog.text == ""
