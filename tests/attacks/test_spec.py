from dataclasses import dataclass

import numpy as np
import pytest

from testbed.attacks.drp import DrpPatch, DrpTrace
from testbed.attacks.fusionripper import FusionRipper
from testbed.attacks.spec import attack_from_dict, attack_spec_to_dict, parse_attack
from testbed.attacks.stealthy import StealthyAttack
from testbed.attacks.trace import TraceInjection
from testbed.errors import UserError


def test_cli_specs_build_the_right_attacks(tmp_path):
    fr = parse_attack("fusionripper:d=0.5,f=1.3", rng=np.random.default_rng(0))
    assert isinstance(fr, FusionRipper) and fr.d == 0.5 and fr.f == 1.3 and fr.start_time == 10.0
    assert isinstance(parse_attack("trace:default"), TraceInjection)
    p = tmp_path / "t.csv"
    p.write_text("t,dev\n0,0\n2,1\n")
    tr = parse_attack(f"trace:{p},start=3,scale=2")
    assert tr.start_time == 3.0 and tr.scale == 2.0 and tr.trace(2.0) == 1.0
    assert isinstance(parse_attack("stealthy"), StealthyAttack)
    assert isinstance(parse_attack("drp-trace"), DrpTrace)
    patch = parse_attack("drp-patch:at=120")
    assert isinstance(patch, DrpPatch) and patch.at == 120.0


def test_spec_to_dict_is_the_scenario_table_form():
    table = attack_spec_to_dict("fusionripper:d=0.7,direction=right")
    assert table == {"kind": "fusionripper", "d": 0.7, "direction": "right"}
    assert attack_from_dict(table).describe()["direction"] == "right"
    assert attack_spec_to_dict("trace:default") == {"kind": "trace", "trace": "default"}


def test_a_boolean_parameter_reads_true_and_false_in_any_case():
    assert attack_spec_to_dict("bound-replay:cancel=false")["cancel"] is False
    assert attack_spec_to_dict("bound-replay:cancel=True")["cancel"] is True  # as a search's spec writes it
    assert attack_from_dict(attack_spec_to_dict("bound-replay:cancel=FALSE")).describe()["cancel"] is False
    with pytest.raises(UserError, match="cancel"):
        attack_from_dict(attack_spec_to_dict("bound-replay:cancel=maybe"))


def test_stealthy_knows_the_defense_cusum():
    @dataclass
    class Defense:
        b: float = 0.8
        tau: float = 0.2

    a = attack_from_dict({"kind": "stealthy", "start": 4}, defense=Defense())
    assert a.knowledge.b == 0.8 and a.knowledge.tau == 0.2 and a.start_time == 4.0
    assert parse_attack("stealthy:b=0.5,ld_std=0.05", defense=Defense()).knowledge.b == 0.5


def test_fusionripper_observation_noise_uses_the_given_stream():
    def switch(seed):
        from testbed.attacks.base import AttackerView
        from testbed.localization.sensors import GnssFix
        from tracks.pose import Pose

        a = parse_attack("fusionripper:start=0,trigger=0.3,obs_std=0.05", rng=np.random.default_rng(seed))
        for i in range(100):
            a.spoof_gnss(GnssFix(i * 0.1, np.zeros(2), np.eye(2)), AttackerView(i * 0.1, Pose(0, 0, 0), -0.25, 0, 1))
        return a.switch_time

    assert switch(3) == switch(3)


@pytest.mark.parametrize(
    ("spec", "word"),
    [
        ("warp:d=1", "unknown attack kind 'warp'"),
        ("", "empty attack spec"),
        ("fusionripper:x=1", "unknown parameter"),
        ("fusionripper:d=abc", "'d' must be a number"),
        ("fusionripper:d=-1", "fusionripper d"),
        ("fusionripper:f=0.5", "fusionripper f"),
        ("fusionripper:direction=up", "direction"),
        ("fusionripper:0.5", "not key=value"),
        ("fusionripper:d=1,d=2", "given twice"),
        ("trace:nosuch", "unknown trace 'nosuch'"),
        ("trace:/no/such/file.csv", "not found"),
        ("drp-patch", "missing required parameter"),
        ("drp-trace:duration=0", "duration"),
        ("stealthy:margin=-1", "margin"),
    ],
)
def test_bad_specs_raise_one_clear_line(spec, word):
    with pytest.raises(ValueError, match=word) as e:
        parse_attack(spec)
    assert "\n" not in str(e.value)


def test_malformed_csv_through_the_spec(tmp_path):
    p = tmp_path / "bad.csv"
    p.write_text("t;dev\n0;0\n")
    with pytest.raises(ValueError, match="header"):
        parse_attack(f"trace:{p}")


@pytest.mark.parametrize(
    ("table", "word"),
    [
        ({"d": 1.0}, "kind"),
        ({"kind": 3}, "string"),
        ({"kind": "fusionripper", "d": True}, "number"),
        ({"kind": "trace", "trace": 1.0}, "string"),
    ],
)
def test_bad_tables_raise(table, word):
    with pytest.raises(ValueError, match=word):
        attack_from_dict(table)
