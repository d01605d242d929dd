import math

import pytest

from vehicles.params import (
    DEV_CHASSIS,
    SEDAN,
    VEHICLES,
    CameraParams,
    VehicleParams,
    get_vehicle,
    vehicle_names,
)


def test_registry_lists_both_vehicles():
    assert vehicle_names() == ["dev-chassis", "sedan"]
    assert get_vehicle("sedan") is SEDAN and get_vehicle("dev-chassis") is DEV_CHASSIS
    assert set(VEHICLES) == set(vehicle_names())


def test_unknown_vehicle_names_the_known_ones():
    with pytest.raises(ValueError, match=r"unknown vehicle 'truck'.*dev-chassis, sedan"):
        get_vehicle("truck")


def test_sedan_is_full_size():
    assert SEDAN.width == 1.90
    assert SEDAN.length == pytest.approx(4.9, abs=0.1)
    assert SEDAN.wheelbase == pytest.approx(2.85, abs=0.05)
    assert SEDAN.mass == pytest.approx(1800.0, rel=0.05)
    assert SEDAN.max_speed >= 27.0 and SEDAN.max_decel >= 4.0


def test_dev_chassis_is_slow_real_size():
    assert DEV_CHASSIS.max_speed <= 5.0
    assert 0.5 <= DEV_CHASSIS.max_steer_rate <= 0.6
    assert 3.0 <= DEV_CHASSIS.max_decel <= 4.0
    assert DEV_CHASSIS.length > 3.0 and DEV_CHASSIS.width > 1.2


def test_axles_sit_inside_the_footprint_around_the_reference_point():
    for v in VEHICLES.values():
        assert -v.length / 2 < v.rear_axle_x < 0.0 < v.front_axle_x < v.length / 2
        assert v.front_axle_x - v.rear_axle_x == pytest.approx(v.wheelbase)


def test_default_camera_is_about_1_4_m_high_pitched_down_320x160():
    for v in VEHICLES.values():
        cam = v.camera
        assert (cam.width, cam.height) == (320, 160)
        assert cam.mount_height == pytest.approx(1.4, abs=0.1)
        assert 0.0 < cam.pitch_deg < 10.0


def test_invalid_parameters_are_rejected():
    with pytest.raises(ValueError, match="field of view"):
        CameraParams(fov_deg=0.0)
    fields = {f: getattr(SEDAN, f) for f in VehicleParams.__dataclass_fields__}
    with pytest.raises(ValueError, match="wheelbase"):
        VehicleParams(**{**fields, "wheelbase": 4.5})
    with pytest.raises(ValueError, match="body width"):
        VehicleParams(**{**fields, "track_width": 1.9})
    assert math.isfinite(SEDAN.cg_x)
