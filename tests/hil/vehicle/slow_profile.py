"""ld3-dev at a 50 ms cycle with 500 ms time-outs, for tests whose starved processes on a shared test machine must
not trip the time-outs, which those tests are not about."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

from hil.link.profile import PROFILES_DIR


def slow_dev_profile(folder: Path) -> str:
    """A copy of ld3-dev in `folder`/slow-dev with the slow cycle and time-outs; its path."""
    profile = folder / "slow-dev"
    shutil.copytree(PROFILES_DIR / "ld3-dev", profile)
    text = (profile / "profile.toml").read_text()
    for key, value in (("cycle_ms", 50), ("command_timeout_ms", 500), ("report_timeout_ms", 500)):
        text = re.sub(rf"^{key} = \d+", f"{key} = {value}", text, flags=re.MULTILINE)
    (profile / "profile.toml").write_text(text)
    return str(profile)
