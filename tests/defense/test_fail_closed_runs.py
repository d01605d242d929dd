"""LD3's fail-closed default against two adaptive MSF-output attacks, end to end on `local` (oracle detector,
MSF localization): an off-map jump (in one tick or ramped over 0.5 s) and a shift timed to an intersection,
where the lines are gated, also after planting an MSF yaw error that a check dead-reckoned from the MSF yaw
would follow. With `fail_closed = False` (the paper's front end and response) the car is lost to
each; the default detects each and stops in lane."""

from __future__ import annotations

from typing import Any

import pytest

from testbed import api
from testbed.attacks.base import Attack, AttackerView, shift_pose
from testbed.attacks.spec import parse_attack
from testbed.localization.estimate import LocalizationEstimate
from tracks.map_api import SemanticMap
from tracks.pose import Pose
from tracks.presets import load_track
from tracks.road import Track
from tracks.semantic_map import TrackMap


class OffMapJump(Attack):
    """From `start` the MSF pose is moved `offset` m left of the lane, past the map's edge: in one tick, or
    linearly over `ramp` s."""

    name = "off-map-jump"

    def __init__(self, start: float = 10.0, offset: float = 20.0, ramp: float = 0.0) -> None:
        super().__init__(start)
        self.offset = offset
        self.ramp = ramp
        self.now = 0.0

    def tamper_msf(self, est: LocalizationEstimate, view: AttackerView) -> LocalizationEstimate:
        elapsed = view.t - self.start_time
        self.now = 0.0 if elapsed < 0 else self.offset * (min(1.0, elapsed / self.ramp) if self.ramp > 0 else 1.0)
        return LocalizationEstimate(est.t, shift_pose(est.pose, view.lane_heading, self.now), est.cov)

    def state(self) -> dict[str, Any]:
        return {"stage": "active" if self.now else "idle", "offset": self.now}

    def describe(self) -> dict[str, Any]:
        return {"kind": self.name, "start": self.start_time, "offset": self.offset, "ramp": self.ramp}


class GatedZoneShift(Attack):
    """The MSF pose is moved `offset` m left once the car is inside an intersection of `smap` (no lane lines,
    Alg. 1 gated there) after `start`, and the shift is held from then on."""

    name = "gated-zone-shift"

    def __init__(self, smap: SemanticMap, start: float = 5.0, offset: float = 2.0) -> None:
        super().__init__(start)
        self.smap = smap
        self.offset = offset
        self.active = False

    def tamper_msf(self, est: LocalizationEstimate, view: AttackerView) -> LocalizationEstimate:
        if not self.active and view.t >= self.start_time:
            self.active = self.smap.is_intersection(view.true_pose)
        if not self.active:
            return est
        return LocalizationEstimate(est.t, shift_pose(est.pose, view.lane_heading, self.offset), est.cov)

    def state(self) -> dict[str, Any]:
        return {"stage": "active" if self.active else "idle", "offset": self.offset if self.active else 0.0}

    def describe(self) -> dict[str, Any]:
        return {"kind": self.name, "start": self.start_time, "offset": self.offset}


class YawPlantedZoneShift(Attack):
    """Against a check dead-reckoned from the MSF yaw: the MSF position stays on the car but its yaw is `eps` rad
    off over the `plant` m before the lines end (`gap` m before the first intersection after `start`); from
    there the MSF pose moves `eps` m left per metre travelled, to the zone's end, and the shift is held."""

    name = "yaw-planted-zone-shift"

    def __init__(self, track: Track, start: float = 5.0, eps: float = 0.05, plant: float = 12.0,
                 gap: float = 14.0) -> None:
        super().__init__(start)
        self.track, self.smap = track, TrackMap(track)
        self.eps, self.plant, self.gap = eps, plant, gap
        self.zone: tuple[float, float] | None = None
        self.offset = 0.0

    def tamper_msf(self, est: LocalizationEstimate, view: AttackerView) -> LocalizationEstimate:
        s = self.smap.project(view.true_pose).s
        if self.zone is None and view.t >= self.start_time:
            self.zone = next(((a, b) for a, b in self.track.intersections if s < a - self.gap - self.plant), None)
        if self.zone is None or s < self.zone[0] - self.gap - self.plant:
            return est
        lines_end = self.zone[0] - self.gap
        self.offset = self.eps * max(0.0, min(s, self.zone[1]) - lines_end)
        pose = shift_pose(est.pose, view.lane_heading, self.offset)
        return LocalizationEstimate(est.t, Pose(pose.x, pose.y, pose.yaw + self.eps), est.cov)

    def state(self) -> dict[str, Any]:
        return {"stage": "active" if self.zone else "idle", "offset": self.offset}

    def describe(self) -> dict[str, Any]:
        return {"kind": self.name, "start": self.start_time, "eps": self.eps, "plant": self.plant, "gap": self.gap}


def _attacks() -> dict[str, Attack]:
    track = load_track("local")
    return {"off-map": OffMapJump(), "off-map-ramp": OffMapJump(ramp=0.5),
            "gated-zone": GatedZoneShift(TrackMap(track)), "yaw-planted": YawPlantedZoneShift(track)}


FAULTS = {"off-map": "off-map", "off-map-ramp": "off-map", "gated-zone": "no-lane-lines",
          "yaw-planted": "no-lane-lines"}
"""A fault each run's summary lists for the defense: the MSF pose off the map, the lines gone."""


def _defense_faults(summary: dict[str, Any]) -> set[str]:
    return {f["kind"] for f in summary["faults"] if f["source"] == "defense"}


def _run(attack: str, fail_closed: bool) -> dict[str, Any]:
    sc = api.scenario("local", localization="msf", defense="ld3", detector="oracle", duration=45.0,
                      defense_params={"fail_closed": fail_closed})
    return api.run(sc, attack=_attacks()[attack]).summary


@pytest.mark.parametrize("attack", list(FAULTS))
def test_the_default_detects_and_stops_in_lane(attack):
    summary = _run(attack, fail_closed=True)
    assert summary["detected"] and summary["consequence"] == "stop_in_lane"
    assert summary["ar_max_dev_m"] < summary["lane_straddle_dev_m"]
    assert FAULTS[attack] in _defense_faults(summary)


@pytest.mark.parametrize("attack", list(FAULTS))
def test_without_failing_closed_the_car_is_lost(attack):
    summary = _run(attack, fail_closed=False)
    assert summary["consequence"] not in ("stop_in_lane", "reach_destination")
    assert summary["detected"] is (attack == "off-map-ramp")  # the ramp is seen, then the response follows it
    assert FAULTS[attack] in _defense_faults(summary)


@pytest.mark.parametrize("spec", ["drp-bend:start=8,shift=-0.3,bend=0.028,ramp=15,duration=35",
                                  "drp-bend:start=8,shift=-0.3,bend=-0.028,ramp=15,duration=35"])
def test_lines_bent_slowly_under_the_heading_check_then_pushed_stop_in_lane(spec):
    """The lines' attacker alone on the highway: the lines bent over 15 s under the heading check's b while their
    offset holds the residual between half b and b, then pushed past b. A trusted pose left to odometry for those
    seconds, on a yaw the bend may turn, is 1.4 m off at the alarm: the true MSF is disowned and the car straddles
    its lane (2.2–2.4 m)."""
    sc = api.scenario("highway", localization="msf", defense="ld3", detector="oracle", duration=45.0)
    summary = api.run(sc, attack=parse_attack(spec)).summary
    assert summary["detected"] and summary["consequence"] == "stop_in_lane"
    assert summary["max_abs_dev_m"] < 0.5


def test_a_shadow_that_chatters_the_steering_leaves_the_odometry_yaw_unbiased():
    """The MSF's attacker swings the pose at each detection and the steering chatters near the control rate. A yaw
    rate sampled once a tick aliases that into a drift of the defense's odometry (0.014 rad in 8 s) that takes this
    run 0.528 m undetected, over the bound on the car (0.52 m); integrated as the period's mean it does not."""
    spec = ("shadow:start=15.0085,spend=0.8674,sustain=0.5923,hspend=0.9163,hsustain=0.7026,spread=0.1059,"
            "along=0.173,direction=right")
    sc = api.scenario("highway", localization="msf", defense="ld3", detector="oracle", duration=45.0)
    summary = api.run(sc, attack=parse_attack(spec)).summary
    assert summary["consequence"] == "reach_destination" and summary["max_abs_dev_m"] < 0.45
