import pytest

from testbed.eval.run.runner import SimRun
from testbed.eval.run.scenario import ScenarioError, load_scenario
from testbed.lane_tracker import TrackerParams


def _scenario(**overrides):
    return load_scenario("urban-straight").with_overrides(**{"duration": 1.0, "detector": "oracle", **overrides})


def test_tracking_defaults_to_camera_detectors_and_needs_a_detector():
    sim = SimRun(_scenario())
    try:
        assert sim.parts.tracker is None  # the oracle reads no camera
    finally:
        sim.close()
    with pytest.raises(ScenarioError, match="tracking needs a lane detector"):
        SimRun(_scenario(detector="none"), tracking=True)


def test_the_tracker_runs_after_the_ld_side_tamper_and_feeds_the_recorded_d_ld():
    shift = 0.5
    sc = _scenario(attack={"kind": "drp-trace", "start": 0.3, "shift": shift, "ramp": 0.0, "duration": 5.0})
    sim = SimRun(sc, tracking=True)
    try:
        result = sim.run()
    finally:
        sim.close()
    assert result.summary["tracking"] is True
    assert sim.parts.tracker.params == TrackerParams()  # a detector without `track_at` gets the default tracker
    last = result.rows[-1]
    assert last.ld_dev - last.phys_dev == pytest.approx(shift, abs=0.03)  # D_LD is of the tracked lines
    tracked_left = sim.parts.tracker.kf.x[0, 0]  # the tracker itself saw the tampered lines
    assert tracked_left == pytest.approx(sim.parts.lane_width / 2 - last.phys_dev - shift, abs=0.03)


def test_the_scenarios_detector_tracking_key_switches_the_tracker():
    from testbed.eval.run.scenario import apply_settings

    on = SimRun(_scenario(detector="classical"))
    off = SimRun(apply_settings(_scenario(detector="classical"), ["detector.tracking=false"]))
    try:
        assert on.parts.tracker is not None and off.parts.tracker is None
    finally:
        on.close()
        off.close()


def test_tracking_is_refused_for_a_detector_without_a_camera():
    from testbed.eval.run.scenario import apply_settings

    with pytest.raises(ScenarioError, match=r"\[detector oracle\] unknown parameter 'tracking'"):
        apply_settings(_scenario(detector="oracle"), ["detector.tracking=true"])


def test_detector_track_at_sets_where_the_tracker_measures_and_needs_tracking():
    from testbed.eval.run.scenario import apply_settings

    for settings, measure_at in ([], (0.0, 6.0, 8.0, 10.0, 12.0)), (["detector.track_at=[0, 6, 8]"], (0.0, 6.0, 8.0)), \
            (["detector.track_at=[]"], ()):
        sim = SimRun(apply_settings(_scenario(detector="classical"), settings))
        try:
            assert sim.parts.tracker.params.measure_at == measure_at
        finally:
            sim.close()
    with pytest.raises(ScenarioError, match=r"needs detector\.tracking = true"):
        SimRun(apply_settings(_scenario(detector="classical"), ["detector.track_at=[6, 8]",
                                                               "detector.tracking=false"]))
    with pytest.raises(ScenarioError, match="increasing distances"):
        apply_settings(_scenario(detector="classical"), ["detector.track_at=[8, 6]"])


def test_a_detector_given_as_an_object_is_tracked_as_the_scenario_says():
    """`ld3 ld closed-loop` hands the run its own detector object: the tracker still measures where the scenario's
    `[detector] track_at` says, and at the default without it."""
    from testbed.eval.run.scenario import apply_settings
    from testbed.lane_detection import LaneDetection, LaneDetector

    class Blank(LaneDetector):
        reads_camera = False

        def detect(self, frame):
            return LaneDetection.empty(frame.t)

    for settings, measure_at in ([], TrackerParams().measure_at), (["detector.track_at=[]"], ()):
        sim = SimRun(apply_settings(_scenario(detector="classical"), settings), detector=Blank(), tracking=True)
        try:
            assert sim.parts.tracker.params.measure_at == measure_at
        finally:
            sim.close()
