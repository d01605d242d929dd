"""A toy attack objective for search tests (no simulation) and a search process to kill mid-way.

`toy_executor` writes a summary whose deviation is a smooth function of the attack's parameters, best for an
off-map attack 30 m to the left (3 m, undetected); every other family stays under 1 m. Run as a module, it
runs a toy search into the folder given, each trial taking `TOY_SLEEP_S` seconds.
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path
from typing import Any

from testbed.attacks.threat import parse_threat
from testbed.eval.campaign.driver import CampaignRun
from testbed.eval.run.scenario import load_scenario
from testbed.eval.run.summary import RunSummary
from testbed.eval.search.attack_search import AttackSearch, SearchSpec
from tests.eval.run.summary_helpers import write_fake_summary


def toy_deviation(attack: dict[str, Any]) -> float:
    if attack["kind"] == "offmap":
        return 3.0 * max(0.0, 1.0 - ((attack["distance"] - 30.0) / 30.0) ** 2)
    return 0.5 * abs(float(attack.get("start", 0.0))) / 30.0


def toy_executor(run: CampaignRun, run_dir: Path) -> RunSummary:
    time.sleep(float(os.environ.get("TOY_SLEEP_S", "0")))
    dev = toy_deviation(run.scenario.attack)
    return write_fake_summary(run_dir, detected=dev < 1.0, detection_time_s=12.0 if dev < 1.0 else None,
                              detection_dev_m=dev if dev < 1.0 else None, max_abs_dev_m=dev,
                              consequence="hit_curb" if dev > 1.5 else "stop_in_lane", lane_straddle_dev_m=0.7)


def toy_spec(budget: int, seed: int = 0, batch: int = 4) -> SearchSpec:
    victim = load_scenario("local").replace(defense="ld3", localization="msf")
    return SearchSpec(victim, parse_threat("msf-output"), budget, seed=seed, batch=batch)


def toy_search(out: Path, budget: int, seed: int = 0, batch: int = 4) -> AttackSearch:
    return AttackSearch(toy_spec(budget, seed, batch), out, workers=1, progress=False, execute=toy_executor)


if __name__ == "__main__":
    toy_search(Path(sys.argv[1]), int(sys.argv[2])).run()
