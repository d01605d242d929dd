"""Each defense declares its own parameter model: SAVIOR's keys are its own, a plugin defense brings its model,
and a `[defense]` key the chosen defense does not declare is refused in one line; summary.json records the same
table as before the split."""

import pytest
from pydantic import Field

from testbed.defense.config import PAPER_MODE, DefenseConfig
from testbed.defense.no_defense import NoDefense
from testbed.defense.registry import DEFENSES, declared_table, defense_settings, explicit_table, resolved_table
from testbed.defense.savior import SaviorConfig
from testbed.eval.run.scenario import Scenario, ScenarioError
from testbed.params import Params, ParamsError
from testbed.registry import Component

SAVIOR_KEYS = ["savior_b", "savior_tau", "savior_speed_std", "savior_accel_std", "savior_yaw_rate_std"]


class GentleParams(Params):
    """A plugin defense's own parameters."""

    patience: float = Field(2.0, gt=0.0, description="seconds before it acts")


class Gentle(NoDefense):
    name = "gentle"

    def __init__(self, params: GentleParams) -> None:
        super().__init__()
        self.params = params


@pytest.fixture
def gentle(monkeypatch):
    component = Component("gentle", lambda params, bicycle: Gentle(params), "a plugin with its own model",
                          params=GentleParams)
    monkeypatch.setattr(DEFENSES, "_plugins", {"gentle": component})
    return component


def test_savior_reads_its_own_model_and_the_loop_its_threshold():
    loop, own = defense_settings("savior", {"savior_b": 2.0, "ar_decel": 3.0, "existence_threshold": 0.6})
    assert own == SaviorConfig(savior_b=2.0, ar_decel=3.0) and loop.existence_threshold == 0.6
    assert not set(SAVIOR_KEYS) & set(DefenseConfig.model_fields)
    with pytest.raises(ParamsError, match=r"^\[defense\] b: not read by defense 'savior'.*savior_b"):
        defense_settings("savior", {"b": 0.45})
    with pytest.raises(ParamsError, match="savior_tau"):
        defense_settings("savior", {"savior_tau": -1.0})


def test_a_plugin_defense_declares_its_own_parameters(gentle):
    loop, own = defense_settings("gentle", {"patience": 5.0})
    assert own == GentleParams(patience=5.0) and loop == DefenseConfig()
    assert gentle.factory(own, None).params.patience == 5.0
    with pytest.raises(ParamsError, match=r"\[defense\] tau: not read by defense 'gentle'.*\(it reads patience\)"):
        defense_settings("gentle", {"tau": 1.0})
    sc = Scenario.build(name="g", track="slr", defense="gentle", defense_params={"patience": 5.0})
    assert explicit_table(sc.defense, sc.defense_params) == {"patience": 5.0}
    with pytest.raises(ScenarioError, match="not read by defense 'gentle'") as err:
        Scenario.build(name="g", track="slr", defense="gentle", defense_params={"savior_b": 1.0})
    assert "\n" not in str(err.value)


def test_the_recorded_table_keeps_every_builtin_key_in_its_old_order(gentle):
    table = resolved_table(*defense_settings("ld3", {"b": 0.45}))
    assert list(table) == [*DefenseConfig.model_fields, *SAVIOR_KEYS] and table["b"] == 0.45
    savior = resolved_table(*defense_settings("savior", {"ar_decel": 3.0, "savior_b": 2.0}))
    assert list(savior) == list(table) and savior["ar_decel"] == 3.0 and savior["savior_b"] == 2.0
    assert resolved_table(*defense_settings("gentle", {}))["patience"] == 2.0
    assert declared_table("savior", table) == {"existence_threshold": 0.5, "ld_lines": "nearer", "ar_decel": 4.0,
                                               **{k: SaviorConfig().model_dump()[k] for k in SAVIOR_KEYS}}


@pytest.mark.parametrize("given", [PAPER_MODE, {**PAPER_MODE, "heading": "fused", "heading_clamp": 0.05},
                                   {"heading": "msf"}, {"heading_clamp": 0.05}, {}],
                         ids=["paper-mode", "paper-mode-clamped", "msf-heading", "clamp", "defaults"])
def test_a_recorded_table_reads_back_as_the_settings_the_run_had(given):
    """What `ld3 replay` and `ld3 figures` rebuild from summary.json: every key recorded, inert ones at their
    defaults (a paper-mode run records heading_clamp and the fail-closed keys it does not run)."""
    settings = defense_settings("ld3", dict(given))
    assert defense_settings("ld3", declared_table("ld3", resolved_table(*settings))) == settings


def test_the_lines_alg3_uses_reach_the_defense_and_the_loops_logged_deviation():
    """`ld_lines` sets Alg. 3 in LD3's and NaiveAR's detection and in the loop's logged D_LD, whatever the defense;
    the paper mode keeps the nearer line; another value is refused."""
    from testbed.eval.run.runner import SimRun
    from testbed.eval.run.scenario import load_scenario

    assert DefenseConfig().ld_lines == "nearer" and DefenseConfig.from_dict(PAPER_MODE).ld_lines == "nearer"
    both = DefenseConfig.from_dict({"ld_lines": "both"})
    for name in ("ld3", "ld3-naive-ar"):
        assert DEFENSES.get(name).factory(both, None).monitor.ld_dev.lines == "both"
    assert defense_settings("savior", {"ld_lines": "both"})[0].ld_lines == "both"
    with pytest.raises(ParamsError, match="ld_lines"):
        DefenseConfig.from_dict({"ld_lines": "middle"})
    for defense in ("ld3", "none"):
        sc = load_scenario("urban-straight").with_overrides(duration=0.5, detector="oracle", defense=defense,
                                                            defense_params={"ld_lines": "both"})
        sim = SimRun(sc, render=False)
        try:
            assert sim.loop.ld_dev.lines == "both"
            if defense == "ld3":
                assert sim.loop.defense.monitor.ld_dev.lines == "both"
        finally:
            sim.close()
