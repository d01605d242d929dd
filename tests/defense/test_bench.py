from testbed.defense.bench import StraightRoadMap, detection_update_benchmark, fusion_update_benchmark
from tracks.pose import Pose


def test_bench_reports_median_and_p99():
    for result in (detection_update_benchmark(200), fusion_update_benchmark(200)):
        assert set(result) == {"median_us", "p99_us"}
        assert 0.0 < result["median_us"] <= result["p99_us"]


def test_bench_map_is_a_two_lane_straight_road():
    smap = StraightRoadMap(lanes=2, width=3.5)
    assert smap.project(Pose(5.0, 3.0, 0.0)) == (1, 5.0, -0.5)
    assert smap.lane_dev(Pose(5.0, 3.0, 0.0), lane=0) == 3.0
