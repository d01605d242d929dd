"""Benchmarks run and report their figures (values are machine-dependent and never asserted against targets)."""

import importlib.util

from testbed.eval.bench import bench_lane_detectors


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
