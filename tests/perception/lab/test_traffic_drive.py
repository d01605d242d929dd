import numpy as np
import pytest

from testbed.errors import UserError
from testbed.eval.run import build as run_build
from testbed.eval.run.scenario import load_scenario
from testbed.perception.lab import traffic_drive as td
from testbed.perception.training.seeds import cells
from testbed.traffic.config import TrafficConfig
from testbed.traffic.fleet import Fleet
from tracks.presets import PRESETS, load_track
from vehicles.params import get_vehicle


def test_the_road_end_margin_is_the_runs():
    assert td.END_MARGIN_M == run_build.END_MARGIN_M


@pytest.mark.parametrize("preset", list(PRESETS))
def test_every_preset_holds_six_cars_with_a_lead_car_close_ahead(preset):
    base = load_scenario(preset)
    for spec in (preset, *(f"{preset}@{c.track_seed}" for c in cells([preset], ["day"]))):
        track = load_track(spec)
        fitted = td.traffic_drive(track, track.ego_lane, base.start_s, base.vehicle, base.speed, 30.0, 6)
        config = TrafficConfig(**fitted.traffic)
        sedan, ego = get_vehicle("sedan"), get_vehicle(base.vehicle)
        fleet = Fleet.place(config, track, track.ego_lane, base.start_s, fitted.speed, np.random.default_rng(0),
                            (sedan.length, sedan.width), (ego.length, ego.width), track.length - td.END_MARGIN_M)
        assert len(fleet.cars) == 6 and 0.1 <= fitted.speed <= base.speed
        lead = min((c for c in fleet.cars if c.lane == track.ego_lane), key=lambda c: c.s)
        assert lead.s - base.start_s == pytest.approx(0.5 * ego.length + td.LEAD_GAP_M + 0.5 * sedan.length)
        assert {c.desired for c in fleet.cars} == {fitted.speed} and {c.speed for c in fleet.cars} == {0.0}
        front = max(c.s for c in fleet.cars if c.lane == track.ego_lane)
        assert front + fitted.speed * 30.0 <= track.length - td.END_MARGIN_M  # still short of the road's end


def test_a_short_road_slows_the_drive_and_too_many_cars_are_refused():
    track, base = load_track("parking-lot"), load_scenario("parking-lot")
    fitted = td.traffic_drive(track, 0, base.start_s, base.vehicle, base.speed, 30.0, 6)
    assert fitted.speed < 0.5 and fitted.traffic["gap"] == td.MIN_GAP_M
    with pytest.raises(UserError, match="lower --traffic"):
        td.traffic_drive(track, 0, base.start_s, base.vehicle, base.speed, 30.0, 12)
    with pytest.raises(UserError, match="number of cars"):
        td.traffic_drive(track, 0, base.start_s, base.vehicle, base.speed, 30.0, 0)
