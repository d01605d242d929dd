"""What a campaign costs before it runs: its runs, their simulated seconds (scenario durations; a run that
stops early takes less), and the wall time estimated from a measured cost per simulated second."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from testbed.eval.campaign.driver import CampaignRun
from testbed.perception.detectors.registry import DETECTORS
from testbed.registry import Capability

WALL_PER_SIM_S_CAMERA = 0.23
WALL_PER_SIM_S_NO_CAMERA = 0.06
"""Seconds one worker (one core) spends per simulated second of a run whose detector reads the rendered
camera (neural), and of one whose detector does not (no frame is rendered): CPU seconds of whole runs
(set-up, loop, outputs; one torch thread) per simulated second on the development machine, FusionRipper
campaign runs, the no-camera figure with the compiled kernels (docs/cluster.md, per-run cost)."""


def wall_per_sim_s(run: CampaignRun) -> float:
    """The measured cost (wall s per simulated s, one worker) of a run of this kind."""
    camera = Capability.CAMERA_IMAGE in DETECTORS.get(run.scenario.detector).provides
    return WALL_PER_SIM_S_CAMERA if camera else WALL_PER_SIM_S_NO_CAMERA


@dataclass(frozen=True)
class CampaignCost:
    """A set of runs: how many, their simulated seconds, and their estimated wall seconds on one worker and
    of the longest run."""

    runs: int
    sim_s: float
    wall_s_one_worker: float
    longest_run_s: float

    def wall_s(self, workers: int) -> float:
        """Estimated wall seconds on `workers` workers of one core each: the runs spread evenly, and never
        less than the longest run."""
        return max(self.wall_s_one_worker / workers, self.longest_run_s)


def campaign_cost(runs: Sequence[CampaignRun]) -> CampaignCost:
    """The cost of `runs`; a search cell (a `trials` tag) costs its trials, each no longer than one run."""
    single = [r.scenario.duration * wall_per_sim_s(r) for r in runs]
    trials = [r.tags.get("trials", 1) for r in runs]
    return CampaignCost(len(runs), sum(r.scenario.duration * n for r, n in zip(runs, trials, strict=True)),
                        sum(c * n for c, n in zip(single, trials, strict=True)), max(single, default=0.0))


def human_duration(seconds: float) -> str:
    """`45 s`, `12 min` or `3.4 h`."""
    if seconds < 60.0:
        return f"{seconds:.0f} s"
    if seconds < 3600.0:
        return f"{seconds / 60.0:.0f} min"
    return f"{seconds / 3600.0:.1f} h"
