import math

import numpy as np
import pybullet as p
import pytest

from tracks.pose import Pose
from vehicles.camera_rig import CameraRig
from vehicles.params import SEDAN, CameraParams


@pytest.fixture
def rig() -> CameraRig:
    return CameraRig(SEDAN.camera)


def test_intrinsics_follow_the_vertical_fov(rig):
    f = 80.0 / math.tan(math.radians(15.0))
    assert np.allclose(rig.K, [[f, 0, 159.5], [0, f, 79.5], [0, 0, 1]])
    assert rig.fov == pytest.approx(math.radians(30.0)) and rig.pitch == pytest.approx(math.radians(5.0))


def test_extrinsics_place_the_camera_on_its_mount(rig):
    T = rig.T_vehicle_from_camera
    assert np.allclose(T[:3, 3], [0.45, 0.0, 1.4])
    optical_axis = T[:3, 2]
    assert np.allclose(optical_axis, [math.cos(rig.pitch), 0.0, -math.sin(rig.pitch)])
    assert np.allclose(T[:3, 0], [0.0, -1.0, 0.0])  # image right is vehicle right


def test_ground_projection_geometry(rig):
    uv = rig.ground_to_pixel(np.array([[10.0, 0.0], [10.0, 1.75], [10.0, -1.75], [-2.0, 0.0]]))
    assert uv[0, 0] == pytest.approx(159.5)  # straight ahead is the centre column
    assert uv[1, 0] < 159.5 < uv[2, 0]  # left of the car is left in the image
    assert uv[1, 1] == pytest.approx(uv[0, 1])
    # row of a ground point 10 m ahead: angle below the horizon minus the pitch
    below = math.atan2(1.4, 10.0 - 0.45) - rig.pitch
    assert uv[0, 1] == pytest.approx(79.5 + rig.K[1, 1] * math.tan(below))
    assert np.isnan(uv[3]).all()  # behind the camera


def test_pixel_to_ground_inverts_and_rejects_the_sky(rig):
    xy = np.array([[5.0, -2.0], [12.0, 0.5], [40.0, 3.0]])
    assert np.allclose(rig.pixel_to_ground(rig.ground_to_pixel(xy)), xy)
    assert np.isnan(rig.pixel_to_ground(np.array([[160.0, 0.0]]))).all()
    homog = np.column_stack((xy, np.ones(3))) @ rig.H.T
    assert np.allclose(homog[:, :2] / homog[:, 2:], rig.ground_to_pixel(xy))


def test_jitter_changes_pitch_and_height(rig):
    jittered = rig.with_jitter(math.radians(1.0), 0.1)
    assert jittered.pitch == pytest.approx(rig.pitch + math.radians(1.0))
    assert jittered.mount_height == pytest.approx(1.5)
    point = np.array([[15.0, 0.0]])
    v0 = rig.ground_to_pixel(point)[0, 1]
    assert rig.with_jitter(math.radians(1.0), 0.0).ground_to_pixel(point)[0, 1] < v0  # looks further down
    assert rig.with_jitter(0.0, 0.1).ground_to_pixel(point)[0, 1] > v0  # sees the ground steeper


def test_matrices_match_pybullet_helpers(rig):
    centred = rig.projection_matrix(0.1, 200.0, tiny_renderer=False)
    assert np.allclose(centred, p.computeProjectionMatrixFOV(30.0, 2.0, 0.1, 200.0))
    pose = Pose(3.0, -4.0, 0.7)
    eye = np.array([*pose.to_world(rig.mount_x, 0.0), rig.mount_height])
    cp, sp = math.cos(rig.pitch), math.sin(rig.pitch)
    forward = np.array([math.cos(pose.yaw) * cp, math.sin(pose.yaw) * cp, -sp])
    up = np.array([math.cos(pose.yaw) * sp, math.sin(pose.yaw) * sp, cp])
    expected = p.computeViewMatrix(eye.tolist(), (eye + forward).tolist(), up.tolist())
    assert np.allclose(rig.view_matrix(pose), expected, atol=1e-6)


@pytest.mark.parametrize("local", [(8.0, 1.2), (6.0, -1.8), (20.0, 0.0), (12.0, 2.5)])
def test_rendered_ground_marker_lands_on_ground_to_pixel(local):
    rig = CameraRig(CameraParams(pitch_deg=4.0))
    pose = Pose(10.0, 5.0, math.radians(30.0))
    hx, hy = 0.0075 * local[0] ** 2, 0.03 * local[0]  # about 6 px tall and 18 px wide at any distance
    cid = p.connect(p.DIRECT)
    try:
        shape = p.createVisualShape(
            p.GEOM_BOX,
            halfExtents=(hx, hy, 0.0005),
            rgbaColor=(1, 0, 0, 1),
            physicsClientId=cid,
        )
        p.createMultiBody(
            0.0,
            baseVisualShapeIndex=shape,
            basePosition=(*pose.to_world(*local), 0.0),
            baseOrientation=p.getQuaternionFromEuler((0.0, 0.0, pose.yaw)),
            physicsClientId=cid,
        )
        _, _, rgba, _, _ = p.getCameraImage(
            rig.width,
            rig.height,
            rig.view_matrix(pose),
            rig.projection_matrix(0.1, 100.0),
            renderer=p.ER_TINY_RENDERER,
            physicsClientId=cid,
        )
    finally:
        p.disconnect(cid)
    img = np.asarray(rgba, dtype=np.uint8).reshape(rig.height, rig.width, 4)
    red = (img[..., 0] > 100) & (img[..., 1] < 60) & (img[..., 2] < 60)
    rows, cols = np.nonzero(red)
    assert len(rows) >= 30
    corners = np.array([[hx, hy], [hx, -hy], [-hx, -hy], [-hx, hy]]) + np.array(local)
    expected = _polygon_centroid(rig.ground_to_pixel(corners))  # the rendered quadrilateral's centroid
    assert abs(cols.mean() - expected[0]) < 0.6
    assert abs(rows.mean() - expected[1]) < 0.6


def test_rendered_ground_patch_covers_exactly_the_pixels_whose_centres_see_it():
    rig = CameraRig(SEDAN.camera)
    centre, hx, hy = (10.0, -0.7), 3.0, 1.3
    cid = p.connect(p.DIRECT)
    try:
        shape = p.createVisualShape(
            p.GEOM_BOX, halfExtents=(hx, hy, 0.0005), rgbaColor=(1, 0, 0, 1), physicsClientId=cid
        )
        p.createMultiBody(0.0, baseVisualShapeIndex=shape, basePosition=(*centre, 0.0), physicsClientId=cid)
        _, _, rgba, _, _ = p.getCameraImage(
            rig.width,
            rig.height,
            rig.view_matrix(Pose(0.0, 0.0, 0.0)),
            rig.projection_matrix(0.1, 100.0),
            renderer=p.ER_TINY_RENDERER,
            physicsClientId=cid,
        )
    finally:
        p.disconnect(cid)
    img = np.asarray(rgba, dtype=np.uint8).reshape(rig.height, rig.width, 4)
    rendered = (img[..., 0] > 100) & (img[..., 1] < 60)
    v, u = np.mgrid[0 : rig.height, 0 : rig.width]
    ground = rig.pixel_to_ground(np.column_stack((u.ravel(), v.ravel())))
    predicted = (np.abs(ground[:, 0] - centre[0]) <= hx) & (np.abs(ground[:, 1] - centre[1]) <= hy)
    assert rendered.sum() > 2000
    assert (predicted.reshape(rendered.shape) != rendered).sum() <= 10


def _polygon_centroid(poly: np.ndarray) -> np.ndarray:
    x, y = poly[:, 0], poly[:, 1]
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    cross = x * yn - xn * y
    area = cross.sum() / 2.0
    return np.array([((x + xn) * cross).sum(), ((y + yn) * cross).sum()]) / (6.0 * area)
