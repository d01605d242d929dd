"""Benchmarks run and account for every frame (short versions of the 10-minute soak)."""

from hil.emulator.bench import round_trip_benchmark, soak


def test_round_trip_benchmark_reports_median_and_p99():
    result = round_trip_benchmark(50)
    assert result["n"] == 50
    assert 0 < result["median_us"] <= result["p99_us"]


def test_soak_loses_no_frame():
    result = soak(sim_seconds=4.0)
    assert result["steps"] == 200
    # per 20 ms: 3 commands + step request out; 5 reports + 2 truth frames + step done back
    assert result["frames_sent"] == 200 * 12
    assert result["lost"] == 0 and result["rejected"] == 0 and result["faults"] == 0
