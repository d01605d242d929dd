"""Run summaries for tests that need a finished run's summary without running one: every field of `RunSummary`
at a plain value, the ones a test names changed."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from testbed.eval.run.summary import HilSummary, RunSummary

FIELDS: dict[str, Any] = {
    "package_version": None, "git_commit": None, "resolved_scenario": {}, "scenario": "s", "seed": 0, "track": "slr",
    "vehicle": "sedan", "attack": None, "threat_model": "none", "defense": "ld3", "condition": "day",
    "detector": "oracle", "localization": "truth", "sim_time_s": 1.0, "wall_time_s": 1.0, "real_time_factor": 1.0,
    "lane_width_m": 3.5, "lane_straddle_dev_m": 0.8, "max_abs_dev_m": 0.1, "final_dev_m": 0.0, "faults": [],
    "consequence": "reach_destination", "detected": False, "detection_time_s": None, "detection_dev_m": None,
    "ar_max_dev_m": None, "ar_stop_dev_m": None, "stop_time_s": None}


def fake_summary(**fields: Any) -> RunSummary:
    """A valid run summary: `FIELDS` with `fields` in their place."""
    return RunSummary(**{**FIELDS, **fields})


HIL_FIELDS: dict[str, Any] = {
    "interface": "virtual", "profile": "ld3-dev", "can_log": None, "can_frames_tx": 0, "can_frames_rx": 0,
    "yaw_rate_source": "chassis", "channel": None, "clock": "lockstep", "pose_source": "sim",
    "consequence_basis": "plant", "odometry_max_abs_dev_m": 0.1, "odometry_final_dev_m": 0.0,
    "odometry_error_max_m": None, "odometry_error_final_m": None, "can_frames_rejected": 0, "can_frames_logged": 0,
    "sensors": "sim"}


def fake_hil_summary(**fields: Any) -> HilSummary:
    """A valid summary of a run over CAN: `FIELDS` and `HIL_FIELDS` with `fields` in their place."""
    return HilSummary(**{**FIELDS, **HIL_FIELDS, **fields})


def write_fake_summary(run_dir: Path, **fields: Any) -> RunSummary:
    """`fake_summary(**fields)` written as `run_dir`/summary.json (the folder made if absent)."""
    summary = fake_summary(**fields)
    run_dir.mkdir(parents=True, exist_ok=True)
    summary.write(run_dir / "summary.json")
    return summary
