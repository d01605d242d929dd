"""The physical road patch seen through the camera: the neural detector's line moves, the figure is written."""

import pytest

from testbed.attacks.spec import attack_spec_to_dict
from testbed.cli import DEMO_PATCH
from testbed.eval.report.drp_figure import drp_before_after


def test_patch_shifts_the_neural_detectors_lane_deviation(tmp_path):
    out = tmp_path / "fig" / "before-after.png"
    clean, patched = drp_before_after(out, attack_spec_to_dict(DEMO_PATCH))
    assert out.is_file() and out.stat().st_size > 10_000
    assert clean.ld_dev is not None and abs(clean.ld_dev) < 0.1  # the car is on the centreline
    assert patched.ld_dev is not None and patched.ld_dev - clean.ld_dev < -0.1  # the right line moved left


def test_patch_figure_rejects_other_attacks(tmp_path):
    with pytest.raises(ValueError, match="drp-patch"):
        drp_before_after(tmp_path / "x.png", attack_spec_to_dict("trace:default"))
