"""A campaign executor whose module takes a while to import: a spawned worker pays that before the run."""

import time
from pathlib import Path

from tests.eval.campaign.campaign_helpers import slow_writer

IMPORT_DELAY_S = 3.0
time.sleep(IMPORT_DELAY_S)


def quick_writer(run, tmp: Path) -> None:
    slow_writer(run, tmp)
