"""Benchmarks run and report their figures (values are machine-dependent and never asserted against targets)."""

import importlib.util
import json

from threadpoolctl import threadpool_info, threadpool_limits

from testbed.cli import EXIT_USAGE, main
from testbed.eval.analysis.bench import (
    LOOP_SECTIONS,
    SectionTimer,
    StepSimulationClock,
    bench_boxes,
    bench_lane_detectors,
    one_core,
)
from testbed.rates import PHYSICS_HZ
from testbed.tiny_boxes import kernel


def test_lane_detector_bench_reports_latency_of_both_detectors_on_one_thread():
    result = bench_lane_detectors(repeats=1, frames_per_episode=2)
    assert result["frames"] == 12 and result["torch_threads"] == 1
    with_onnx = importlib.util.find_spec("onnxruntime") is not None
    if not with_onnx:
        assert "onnxruntime is not installed" in result["neural-onnx"]
    for name in ("neural", "classical", *(("neural-onnx",) if with_onnx else ())):
        r = result[name]
        assert 0.0 < r["ms_median"] <= r["ms_p99"]
        assert 0.0 < r["cpu_ms_median"] <= r["cpu_ms_p99"]


def test_one_core_leaves_the_blas_pools_one_thread():
    before = {pool["prefix"]: pool["num_threads"] for pool in threadpool_info()}
    try:
        one_core()
        blas = [pool["num_threads"] for pool in threadpool_info() if pool["user_api"] == "blas"]
        assert blas and set(blas) == {1}
    finally:
        threadpool_limits(limits=before)


def test_loop_bench_without_camera_reports_both_real_time_factors_and_a_complete_split(capsys):
    assert main(["bench", "loop", "--camera", "off", "--scenario", "highway", "--speed", "27", "--localization",
                 "msf", "--detector", "none", "--seconds", "0.5", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["camera"] is False and result["sim_time_s"] == 0.5 and result["physics_hz"] == PHYSICS_HZ
    assert result["physics_steps"] == round(0.5 * PHYSICS_HZ)
    assert result["real_time_factor"] > 0 and result["bare_physics_real_time_factor"] > 0
    assert 0 < result["ratio_to_in_loop_physics"] < 1 and result["in_loop_physics_real_time_factor"] > 0
    assert set(result["time_fraction"]) == {*LOOP_SECTIONS, "rest"}
    assert result["time_fraction"]["physics"] > 0 and result["time_fraction"]["localization"] > 0
    assert result["time_fraction"]["render"] == 0 and result["time_fraction"]["detector"] == 0


def test_loop_bench_with_camera_splits_the_frame_into_bodies_ground_and_effects(capsys):
    assert main(["bench", "loop", "--camera", "on", "--detector", "oracle", "--seconds", "0.5", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["camera"] is True and result["resolution"] == "320x160"
    assert result["boxes_drawn_by"] == ("tinyrenderer" if kernel() is None else "clone")
    assert set(result["time_fraction"]) == {*LOOP_SECTIONS, "rest"}
    for section in ("render", "ground canvas", "image effects", "tile streaming", "detector"):
        assert result["time_fraction"][section] > 0, section


def test_box_bench_times_the_clone_against_tinyrenderer_on_the_same_pictures():
    result = bench_boxes(frames=5)
    if kernel() is None:
        assert result is None
        return
    assert result["identical"] is True
    for name in ("clone", "tinyrenderer"):
        assert 0.0 < result[name]["ms_median"] <= result[name]["ms_p99"]


def test_loop_bench_refuses_a_camera_detector_without_camera_and_loop_options_elsewhere(capsys):
    assert main(["bench", "loop", "--camera", "off", "--detector", "neural", "--seconds", "0.5"]) == EXIT_USAGE
    assert "--camera on" in capsys.readouterr().err
    assert main(["bench", "map", "--camera", "off"]) == EXIT_USAGE
    assert "only apply to `ld3 bench loop`" in capsys.readouterr().err
    assert main(["bench", "map", "--set", "rates.control_hz=40"]) == EXIT_USAGE
    assert "--set only apply to `ld3 bench loop`" in capsys.readouterr().err


def test_loop_bench_runs_the_scenario_with_the_settings_given(capsys):
    assert main(["bench", "loop", "--camera", "off", "--detector", "none", "--seconds", "0.5", "--set",
                 "rates.control_hz=40", "--set", "rates.physics_hz=120", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["control_hz"] == 40 and result["physics_hz"] == 120 and result["physics_steps"] == 60
    assert main(["bench", "loop", "--camera", "off", "--detector", "none", "--set", "rates.control_hz=50"]) \
        == EXIT_USAGE
    assert "must divide rates.control_hz" in capsys.readouterr().err


def test_step_simulation_clock_times_the_steps_inside_it_and_restores_pybullet():
    import pybullet as pb

    original = pb.stepSimulation
    client = pb.connect(pb.DIRECT)
    try:
        with StepSimulationClock() as clock:
            assert pb.stepSimulation is not original
            for _ in range(5):
                pb.stepSimulation(physicsClientId=client)
        assert clock.seconds > 0
        seconds = clock.seconds
        pb.stepSimulation(physicsClientId=client)
        assert pb.stepSimulation is original and clock.seconds == seconds
    finally:
        pb.disconnect(client)


def test_section_timer_counts_nested_calls_once():
    now = [0.0]

    class Parts:
        def outer(self) -> None:
            now[0] += 2.0
            self.inner()
            now[0] += 1.0

        def inner(self) -> None:
            now[0] += 3.0

    parts, timer = Parts(), SectionTimer(clock=lambda: now[0])
    timer.wrap(parts, "outer", "a")
    timer.wrap(parts, "inner", "b")
    parts.outer()
    parts.inner()
    assert dict(timer.seconds) == {"a": 3.0, "b": 6.0}
