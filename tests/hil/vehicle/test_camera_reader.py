"""Camera reader: a video file through OpenCV arrives frame by frame at its rate, a camera that stops is a stall;
a calibration file maps the road a camera sees (any mount, pitch, yaw, roll) into the detector's rig.
"""

from __future__ import annotations

import dataclasses
import time

import cv2
import numpy as np
import pytest

from hil.vehicle.camera_calibration import CameraCalibration, Rectifier, view_check
from hil.vehicle.camera_reader import CameraReader, HandedFrames, OpenCvSource
from vehicles.camera_rig import CameraRig
from vehicles.params import CameraParams

RIG = CameraRig(CameraParams())


def _video(path, frames: int = 8, fps: float = 20.0):
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), fps, (64, 32))
    for k in range(frames):
        writer.write(np.full((32, 64, 3), 20 * k + 10, np.uint8))
    writer.release()


def test_a_video_file_plays_at_its_rate_and_its_end_is_a_stall(tmp_path):
    _video(tmp_path / "drive.avi")
    start = time.monotonic()
    reader = CameraReader(OpenCvSource(f"video:{tmp_path / 'drive.avi'}"), lambda: time.monotonic() - start,
                          stall_s=0.3)
    try:
        assert reader.wait_frame(8, timeout=5.0)
        elapsed = time.monotonic() - start
        frame = reader.capture(elapsed)
        assert frame.image.shape == (32, 64, 3) and abs(int(frame.image[0, 0, 0]) - 150) < 8
        assert reader.capture(elapsed).image is None  # nothing new since
        assert elapsed >= 0.3  # paced at 20 fps, not read at once
        time.sleep(0.1)
        assert reader.ended == "end of stream" and reader.stalled(elapsed) is None
        assert reader.stalled(elapsed + 0.5).startswith("no camera frame for")
    finally:
        reader.close()


def test_bad_camera_specs_are_user_errors(tmp_path):
    with pytest.raises(ValueError, match="v4l2:/dev/videoN or video:PATH"):
        OpenCvSource("usb:0")
    with pytest.raises(ValueError, match="cannot open camera"):
        OpenCvSource(f"video:{tmp_path / 'missing.avi'}")


def test_handed_frames_that_stop_coming_stall_the_camera():
    now = [0.0]
    frames = HandedFrames()
    reader = CameraReader(frames, lambda: now[0], stall_s=0.5)
    try:
        frames.put(np.zeros((4, 4, 3), np.uint8))
        assert reader.wait_frame(1, 2.0) and reader.capture(0.0).image is not None
        now[0] = 0.4
        assert reader.stalled(0.4) is None and reader.stalled(0.6).startswith("no camera frame for 0.60 s")
    finally:
        reader.close()


def _calibration(tmp_path, pitch_deg: float, distortion: str = "[]", mount=(1.1, 1.3),
                 extra: str = "") -> CameraCalibration:
    k = RIG.K
    (tmp_path / "cam.toml").write_text(
        f"[intrinsics]\nwidth = {RIG.width}\nheight = {RIG.height}\nfx = {k[0, 0]}\nfy = {k[1, 1]}\ncx = {k[0, 2]}\n"
        f"cy = {k[1, 2]}\ndistortion = {distortion}\n[extrinsics]\nmount_x = {mount[0]}\n"
        f"mount_height = {mount[1]}\npitch_deg = {pitch_deg}\n{extra}")
    return CameraCalibration.load(tmp_path / "cam.toml")


def test_a_camera_calibrated_as_the_rig_is_passed_through(tmp_path):
    image = np.random.default_rng(0).integers(0, 255, (RIG.height, RIG.width, 3), dtype=np.uint8)
    same = _calibration(tmp_path, RIG.params.pitch_deg, mount=(RIG.params.mount_x, RIG.params.mount_height))
    assert same.rig_params(RIG.params) == RIG.params
    rectify = Rectifier(same, RIG)
    assert rectify.coverage == 1.0
    assert np.array_equal(rectify(image), image)


OTHER = CameraCalibration(width=1280, height=720, fx=1150.0, fy=1140.0, cx=655.0, cy=380.0,
                          distortion=(-0.24, -0.08, 0.001, 0.0, 0.1), mount_x=1.6, mount_height=1.23,
                          pitch_deg=3.0, mount_y=0.15, yaw_deg=1.5, roll_deg=-1.0)


def _seen_by(calibration: CameraCalibration, xyz: np.ndarray) -> np.ndarray:
    """Distorted pixels of vehicle-frame points (N, 3) in the calibrated camera (an independent projection)."""
    rot = calibration.vehicle_from_camera.T
    rvec, _ = cv2.Rodrigues(rot)
    pixels, _ = cv2.projectPoints(xyz.astype(float), rvec, -rot @ calibration.mount, calibration.matrix,
                                  np.array(calibration.distortion))
    return pixels[:, 0, :]


def test_the_road_of_a_camera_at_another_mount_pitch_yaw_and_roll_lands_where_the_rig_sees_it():
    rectify = Rectifier(OTHER, RIG)
    ground = np.array([[6.0, 1.7], [9.0, -1.9], [14.0, 0.4], [22.0, -1.6], [30.0, 2.0]])
    for x, y in ground:
        image = np.zeros((OTHER.height, OTHER.width, 3), np.uint8)
        u, v = _seen_by(OTHER, np.array([[x, y, 0.0]]))[0]
        cv2.circle(image, (round(u), round(v)), 5, (255, 255, 255), -1)
        out = rectify(image)[:, :, 0].astype(float)
        vv, uu = np.nonzero(out > 64)
        assert len(vv), (x, y)
        weight = out[vv, uu]
        centre = np.array([np.average(uu, weights=weight), np.average(vv, weights=weight)])
        assert centre == pytest.approx(RIG.ground_to_pixel(np.array([[x, y]]))[0], abs=0.8), (x, y)


def test_above_the_horizon_the_rig_shows_the_same_directions():
    rectify = Rectifier(OTHER, RIG)
    u, v = np.array([40, 160, 300]), np.array([5, 20, 40])  # rig rows above its horizon (row 53)
    direction = np.column_stack([u, v, np.ones(3)]) @ np.linalg.inv(RIG.K).T @ RIG.T_vehicle_from_camera[:3, :3].T
    expected = _seen_by(OTHER, OTHER.mount + 1e4 * direction)
    got = np.column_stack([rectify.maps[0][v, u], rectify.maps[1][v, u]])
    assert got == pytest.approx(expected, abs=0.05)


def test_what_the_camera_does_not_see_is_black_and_counted_out_of_the_coverage():
    narrow = dataclasses.replace(OTHER, fx=3000.0, fy=3000.0, distortion=())
    rectify = Rectifier(narrow, RIG)
    out = rectify(np.full((720, 1280, 3), 200, np.uint8))
    assert out[-1, 0].tolist() == [0, 0, 0] and out[RIG.height // 2 + 20, RIG.width // 2].tolist() == [200] * 3
    assert rectify.coverage < 0.7 and "check pitch_deg" in view_check(narrow, RIG)
    assert Rectifier(OTHER, RIG).coverage > 0.9 and view_check(OTHER, RIG) is None


def test_a_frame_of_another_size_than_the_calibration_is_refused(tmp_path):
    with pytest.raises(ValueError, match="frame is 160x80, its calibration 320x160"):
        Rectifier(_calibration(tmp_path, 5.0), RIG)(np.zeros((80, 160, 3), np.uint8))


def test_a_broken_calibration_file_names_what_is_wrong(tmp_path):
    (tmp_path / "cam.toml").write_text("[intrinsics]\nwidth = 320\n")
    with pytest.raises(ValueError, match="missing or bad entry"):
        CameraCalibration.load(tmp_path / "cam.toml")
    with pytest.raises(ValueError, match="distortion takes"):
        _calibration(tmp_path, 5.0, "[0.1, 0.2]")
    with pytest.raises(ValueError, match="mount_height must be above the ground"):
        _calibration(tmp_path, 5.0, mount=(1.0, -0.2))
    with pytest.raises(ValueError, match=r"missing or bad entry .*could not convert"):
        _calibration(tmp_path, 5.0, extra="yaw_deg = 'left'\n")
    assert _calibration(tmp_path, 5.0, extra="yaw_deg = 2\nroll_deg = -1.5\nmount_y = 0.2\n").roll_deg == -1.5
