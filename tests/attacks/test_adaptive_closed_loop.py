"""Each adaptive family on a short closed-loop run: it acts (its stage leaves idle), moves what its threat model
lets it move, and the run records the threat model."""


import pytest

from testbed.defense.config import PAPER_MODE
from testbed.eval.run.runner import run_scenario
from testbed.eval.run.scenario import load_scenario

CASES = {
    "zone": ({"kind": "zone", "zone": "intersection", "lateral": -1.5, "ramp": 0.2, "hold": 2.0}, "msf-output"),
    "offmap": ({"kind": "offmap", "start": 3.0, "distance": 25.0}, "msf-output"),
    "burst": ({"kind": "burst", "start": 3.0, "spend": 0.9, "spread": 1.0, "sustain": 0.9}, "msf-output"),
    "coordinated": ({"kind": "coordinated", "start": 3.0, "rate": 1.0, "limit": 2.0}, "msf-output,ld-output"),
    "gnss-drift": ({"kind": "gnss-drift", "start": 3.0, "rate": 1.0, "limit": 3.0}, "gnss"),
    "heading": ({"kind": "heading", "start": 3.0, "bias": -0.1, "ramp": 1.0}, "msf-output"),
    "unchecked": ({"kind": "unchecked", "start": 3.0, "lateral": 3.0, "yaw": 0.1, "ramp": 0.5}, "msf-output"),
    "along": ({"kind": "along", "start": 3.0, "along": 20.0, "ramp": 1.0}, "msf-output"),
    "response": ({"kind": "response", "start": 3.0, "along": 15.0, "lead": 1.0, "force": 2.0,
                  "policy": "centre"}, "msf-output"),
    "strike": ({"kind": "strike", "start": 3.0, "spend": 0.9, "hspend": 0.9, "spread": 0.5}, "msf-output"),
    "bound-replay": ({"kind": "bound-replay", "start": 3.0}, "msf-output"),
    "shadow": ({"kind": "shadow", "start": 3.0, "sustain": 1.0, "hsustain": 1.2, "spread": 2.0}, "msf-output"),
}


@pytest.mark.parametrize("family", sorted(CASES))
def test_each_family_acts_in_a_short_closed_loop_run(family):
    attack, threat = CASES[family]
    # 40 m before local's first intersection (s = 350 m), so the zone attack meets it within the run
    sc = load_scenario("local").replace(defense="ld3", localization="msf", duration=9.0, start_s=310.0,
                                        attack=attack)
    result = run_scenario(sc, None)
    s = result.summary
    assert s["threat_model"] == threat and s["attack"]["kind"] == family
    offsets = [r.attack_offset for r in result.rows if r.attack_offset]
    assert offsets, f"{family} never offset anything"
    stages = {r.attack_stage for r in result.rows}
    assert stages - {"idle"}, stages
    if family == "coordinated":  # outside LD3's threat model: MSF and lines agree, so nothing is detected
        assert not s["detected"] and s["consequence"] == "hit_curb"
    if family == "heading":  # the heading check sees the biased yaw before the car leaves its lane
        assert s["detected"] and s["consequence"] == "stop_in_lane"
    if family == "offmap":
        assert max(abs(r.attack_offset) for r in result.rows) == 25.0
    if family == "unchecked":  # LD3 steers on checked poses only: the moves between detections reach nothing
        assert not s["detected"] and s["max_abs_dev_m"] < 0.2 and s["consequence"] == "reach_destination"
    if family == "bound-replay":  # the linear program's worst inputs stay within its CUSUM budgets
        assert max(abs(r.attack_offset) for r in result.rows) <= 0.2 + 2.0 + 1e-9
    if family == "response":  # the forced alarm, then an MSF held on the centre line: disowned, stop in lane
        assert s["detected"] and s["consequence"] == "stop_in_lane"
        assert "msf-disowned" in {f["kind"] for f in s["faults"]}
    if family == "shadow":  # spending both budgets moves the car, but not out of its lane
        assert 0.1 < s["max_abs_dev_m"] < 0.45 and s["consequence"] in ("reach_destination", "stop_in_lane")


def test_the_paper_mode_steers_on_unchecked_ticks_and_is_moved():
    attack, _ = CASES["unchecked"]
    sc = load_scenario("local").replace(defense="ld3", localization="msf", duration=9.0, start_s=310.0,
                                        attack=attack)
    paper = run_scenario(sc.replace(defense_params=dict(PAPER_MODE)), None).summary
    assert paper["max_abs_dev_m"] > 0.5


def test_the_paper_mode_without_a_heading_check_is_moved_further_by_the_shadow():
    attack, _ = CASES["shadow"]
    sc = load_scenario("local").replace(defense="ld3", localization="msf", duration=9.0, start_s=310.0,
                                        attack=attack)
    default = run_scenario(sc, None).summary
    paper = run_scenario(sc.replace(defense_params=dict(PAPER_MODE)), None).summary
    assert paper["max_abs_dev_m"] > default["max_abs_dev_m"] + 0.2
