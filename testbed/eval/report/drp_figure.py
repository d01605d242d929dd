"""Before/after figure of the physical dirty-road-patch attack (`drp-patch`, paper §6.2).

The same camera pose on the ego-lane centreline, `ahead` metres before the patch, is rendered on the clean
road and on the road with the patch painted in; the lane detector reads both frames. The figure shows the
two frames with the detected lines drawn over them, and reports Alg. 3's LD deviation D_LD for each: the
vehicle is on the centreline, so any D_LD beyond the detector's own error is the patch's doing.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from testbed.defense.ld_deviation import LdDeviation
from testbed.errors import UserError
from testbed.eval.run.scenario import load_scenario
from testbed.eval.run.video import draw_detection
from testbed.lane_detection import LaneDetection


@dataclass(frozen=True)
class PatchView:
    """One rendered frame: the image with the detection drawn, the detection, and its D_LD (m, + left)."""

    image: np.ndarray
    detection: LaneDetection
    ld_dev: float | None


def _view(track: str, detector: str, attack: dict[str, Any] | None, s: float) -> PatchView:
    from testbed.eval.run.runner import SimRun

    sc = load_scenario(track).with_overrides(detector=detector, defense="none", duration=1.0, start_s=s)
    sc = sc if attack is None else sc.with_overrides(attack=attack)
    sim = SimRun(sc, render=True)
    try:
        pose = sim.parts.start
        sim.parts.streamer.update(pose)
        frame = sim.parts.camera.capture(0.0, pose)
        ld = sim.parts.detector.detect(frame)
        width = sim.parts.smap.lane_width(pose, sim.parts.lane)
        d = LdDeviation(sim.parts.defense_config.existence_threshold).update(ld, width)
        return PatchView(draw_detection(frame.image, ld, sim.parts.rig), ld, d)
    finally:
        sim.close()


def drp_before_after(out: Path, attack: dict[str, Any], track: str = "urban-straight", detector: str = "neural",
                     ahead: float = 8.0) -> tuple[PatchView, PatchView]:
    """Render the clean and the patched road `ahead` m before the patch of the `drp-patch` attack table `attack`
    (as `attack_spec_to_dict` gives it); write `out` (PNG)."""
    if attack.get("kind") != "drp-patch" or "at" not in attack:
        raise UserError(f"the patch figure needs a drp-patch attack with its place `at`, got {attack!r}")
    s = float(attack["at"]) - ahead
    clean, patched = _view(track, detector, None, s), _view(track, detector, attack, s)
    fig = Figure(figsize=(11, 4.2))
    axes = fig.subplots(1, 2)
    for ax, view, label in ((axes[0], clean, "clean road"), (axes[1], patched, "with the dirty-road patch")):
        ax.imshow(view.image)
        ax.set_axis_off()
        dev = "none" if view.ld_dev is None else f"{view.ld_dev:+.2f} m"
        ax.set_title(f"{label}: D_LD = {dev} (car on the centreline)", fontsize=10)
    spec = ", ".join(f"{k}={v:g}" for k, v in attack.items() if k != "kind")
    fig.suptitle(f"drp-patch:{spec} on {track}, {detector} detector, {ahead:g} m before the patch", fontsize=10)
    fig.tight_layout()
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=120)
    return clean, patched
