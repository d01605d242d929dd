"""The chassis table over CAN (`ld3 campaign chassis`, paper Table "pixkit_devs"): the development chassis
driven through the CAN bridge against the emulated chassis ECU on python-can's virtual bus.

Parking lot (one 3.5 m lane), dev-chassis, `ld3-dev` profile, at 2 and 4 m/s; per speed, under the default
trace injection LD3, LD3-NaiveAR and no defense, and benign LD3; each `REPETITIONS` times (repetition k:
noise seed k, attack start 3 + k/2 s). Like the paper, the response brakes at `AR_DECEL` (< 3 m/s²) to
lengthen it, and the lane lines come from the map (oracle detector). Registered through the `ld3.campaigns`
entry point, so that testbed never imports hil.
"""

from __future__ import annotations

from pathlib import Path

from hil.link.profile import DEFAULT_PROFILE
from testbed.eval.campaign.driver import CampaignRun
from testbed.eval.experiments.campaigns import CampaignSpec
from testbed.eval.report.summary_stats import consequences, fmt_mean_sd, response_max_dev, stop_dev
from testbed.eval.run.scenario import load_scenario
from testbed.eval.run.summary import HilSummary, RunSummary

SPEEDS = (2.0, 4.0)
REPETITIONS = 3
AR_DECEL = 2.5
"""Response deceleration (m/s²): the paper used < 3 m/s² on the chassis."""
SETTINGS: dict[str, tuple[str, dict[str, float], bool]] = {
    "ld3": ("ld3", {"ar_decel": AR_DECEL}, True),
    "naive": ("ld3-naive-ar", {"max_decel": AR_DECEL}, True),
    "none": ("none", {}, True),
    "benign": ("ld3", {"ar_decel": AR_DECEL}, False),
}
"""Setting -> (defense, [defense] parameters, attacked)."""


def chassis_runs(detector: str) -> list[CampaignRun]:
    """Every speed × setting × repetition; the lane detector is the map's (oracle), as on the paper's chassis."""
    runs = []
    for speed in SPEEDS:
        base = load_scenario("parking-lot").with_overrides(speed=speed, detector="oracle", localization="msf",
                                                           name=f"chassis-{speed:g}")
        for setting, (defense, params, attacked) in SETTINGS.items():
            for rep in range(REPETITIONS):
                attack = {"kind": "trace", "trace": "default", "start": 3.0 + 0.5 * rep} if attacked else None
                sc = base.with_overrides(seed=rep, defense=defense, defense_params=dict(params), attack=attack)
                runs.append(CampaignRun(f"{speed:g}mps/{setting}-rep{rep}", sc,
                                        {"speed": speed, "setting": setting, "rep": rep}))
    return runs


def run_over_can(run: CampaignRun, run_dir: Path) -> RunSummary:
    """Executor: the run over the virtual CAN bus against the in-process ECU emulator (lockstep). The simulator
    is imported here, on a worker, so that listing campaigns loads no physics engine."""
    from hil.emulator.scenario_run import LinkConfig, run_hil_scenario

    return run_hil_scenario(run.scenario, run_dir, LinkConfig("virtual", profile=DEFAULT_PROFILE)).record


def chassis_table(done: list[tuple[CampaignRun, HilSummary]], out: Path) -> str:
    lines = ["Deviations are |physical D| in m, (mean, std) over the repetitions: detection = before the alarm, "
             "max = during the response (attacked LD3 and NaiveAR) or the whole run, stop = at standstill or the "
             "end.", "",
             "| speed | setting | runs | detected | detection dev | max dev | stop dev | consequences | CAN frames "
             "tx / rx / rejected |", "|---|---|---|---|---|---|---|---|---|"]
    for speed in SPEEDS:
        for setting in SETTINGS:
            sums = [s for r, s in done if r.tags["speed"] == speed and r.tags["setting"] == setting]
            if not sums:
                continue
            lines.append(f"| {speed:g} m/s | {setting} | {len(sums)} | {sum(bool(s.detected) for s in sums)}"
                         f"/{len(sums)} | {fmt_mean_sd(s.detection_dev_m for s in sums)} "
                         f"| {fmt_mean_sd(response_max_dev(s) for s in sums)} "
                         f"| {fmt_mean_sd(stop_dev(s) for s in sums)} | {consequences(sums)} "
                         f"| {sum(s.can_frames_tx for s in sums)} / {sum(s.can_frames_rx for s in sums)} / "
                         f"{sum(s.can_frames_rejected for s in sums)} |")
    return "\n".join(lines)


CHASSIS = CampaignSpec("chassis", "dev chassis over CAN (ld3-dev profile, virtual bus, ECU emulator): parking lot "
                       "at 2 and 4 m/s, trace injection × LD3 / NaiveAR / none and benign LD3, 3 repetitions, "
                       f"response at {AR_DECEL:g} m/s² (paper chassis table)",
                       chassis_runs, chassis_table, run_over_can)
