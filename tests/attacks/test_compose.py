"""Composed attacks: every hook runs through the members in list order; capabilities and specs are the union."""

from typing import Any

import numpy as np
import pytest

from testbed.attacks.base import Attack, AttackerView
from testbed.attacks.compose import AttackChain, threat_model_of
from testbed.attacks.spec import attack_tables, build_attack, specs_to_value
from testbed.attacks.threat import (
    ThreatCapability,
    parse_threat,
    reaches_lines,
    threat_label,
    within_ld3_threat_model,
)
from testbed.errors import UserError
from testbed.lane_detection import LaneDetection
from testbed.localization.estimate import LocalizationEstimate
from testbed.localization.sensors import GnssFix
from tracks.pose import Pose


class Recorder(Attack):
    """Appends its tag to a shared log on every hook and moves the pose 1 m east (so order is visible)."""

    capabilities = frozenset({ThreatCapability.MSF_OUTPUT})

    def __init__(self, tag: str, log: list[str]) -> None:
        super().__init__(0.0)
        self.tag, self.log = tag, log
        self.name = tag

    def spoof_gnss(self, fix: GnssFix, view: AttackerView) -> GnssFix:
        self.log.append(f"gnss:{self.tag}")
        return fix

    def tamper_msf(self, est: LocalizationEstimate, view: AttackerView) -> LocalizationEstimate:
        self.log.append(f"msf:{self.tag}:{est.pose.x:.0f}")
        return LocalizationEstimate(est.t, Pose(est.pose.x + 1.0, est.pose.y, est.pose.yaw), est.cov)

    def tamper_ld(self, ld: LaneDetection, view: AttackerView) -> LaneDetection:
        self.log.append(f"ld:{self.tag}")
        return ld

    def state(self) -> dict[str, Any]:
        return {"stage": self.tag, "switch_time": None, "offset": 0.5}

    def describe(self) -> dict[str, Any]:
        return {"kind": self.tag}


VIEW = AttackerView(1.0, Pose(0.0, 0.0, 0.0), 0.0, 0.0, 10.0)


def test_hooks_run_in_list_order():
    log: list[str] = []
    chain = AttackChain([Recorder("a", log), Recorder("b", log), Recorder("c", log)])
    est = chain.tamper_msf(LocalizationEstimate(1.0, Pose(0.0, 0.0, 0.0), np.eye(3)), VIEW)
    chain.spoof_gnss(GnssFix(1.0, np.zeros(2), np.eye(2)), VIEW)
    chain.tamper_ld(LaneDetection.empty(1.0), VIEW)
    assert log == ["msf:a:0", "msf:b:1", "msf:c:2", "gnss:a", "gnss:b", "gnss:c", "ld:a", "ld:b", "ld:c"]
    assert est.pose.x == 3.0
    assert chain.describe() == [{"kind": "a"}, {"kind": "b"}, {"kind": "c"}]
    state = chain.state()
    assert state["stage"] == "a+b+c" and state["offset"] == pytest.approx(1.5) and len(state["members"]) == 3


def test_threat_model_is_the_union_of_the_members():
    chain = build_attack([{"kind": "trace"}, {"kind": "drp-trace"}])
    assert isinstance(chain, AttackChain)
    assert threat_model_of(chain) == {ThreatCapability.MSF_OUTPUT, ThreatCapability.LD_OUTPUT}
    assert threat_label(threat_model_of(chain)) == "msf-output,ld-output"
    assert not within_ld3_threat_model(threat_model_of(chain))
    assert within_ld3_threat_model(threat_model_of(build_attack({"kind": "fusionripper"})))
    assert threat_model_of(None) == frozenset()


def test_an_attacker_of_one_source_is_within_ld3_s_claims_and_of_both_outside():
    drp = threat_model_of(build_attack({"kind": "drp-trace"}))
    assert drp == {ThreatCapability.LD_OUTPUT}
    assert within_ld3_threat_model(drp) and reaches_lines(drp)  # paper §6.2: the LD side alone, the MSF benign
    assert within_ld3_threat_model({ThreatCapability.ROAD_PAINT})
    assert not within_ld3_threat_model({ThreatCapability.GNSS, ThreatCapability.ROAD_PAINT})
    assert not reaches_lines({ThreatCapability.GNSS, ThreatCapability.MSF_OUTPUT})


def test_attack_values_and_specs():
    assert build_attack(None) is None
    assert specs_to_value([]) is None
    assert specs_to_value(["trace:default"]) == {"kind": "trace", "trace": "default"}
    assert specs_to_value(["trace", "zone:index=1"]) == [{"kind": "trace"}, {"kind": "zone", "index": 1}]
    with pytest.raises(UserError, match="non-empty list"):
        attack_tables([])
    with pytest.raises(UserError, match="at least two"):
        AttackChain([Recorder("a", [])])


def test_threat_parsing_names_the_known_capabilities():
    assert parse_threat("gnss, ld-output") == {ThreatCapability.GNSS, ThreatCapability.LD_OUTPUT}
    with pytest.raises(UserError, match="known: gnss, msf-output, ld-output, road-paint"):
        parse_threat("gps")
    with pytest.raises(UserError, match="names no capability"):
        parse_threat("")
