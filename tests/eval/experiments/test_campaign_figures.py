"""Which campaigns' runs draw their figures at their end and which leave them to `ld3 figures`: each campaign's
own choice, said in its help and its report, overridden by `--figures-now` or `--figures-later`."""

import pytest

from testbed.cli import main
from testbed.eval.campaign.driver import run_and_write, run_and_write_data
from testbed.eval.experiments import campaigns
from testbed.eval.experiments.campaigns import CAMPAIGNS, LATER_NOTE


def test_a_campaign_that_leaves_figures_for_later_says_so_and_writes_the_standard_outputs():
    later = [spec.name for spec in CAMPAIGNS if spec.figures_later]
    assert "fusionripper-grid" in later
    for spec in CAMPAIGNS:
        assert spec.help.endswith(LATER_NOTE) == spec.figures_later, spec.name
        if spec.figures_later:
            assert spec.execute is run_and_write and spec.searches is None, spec.name


@pytest.mark.parametrize(("name", "run", "flags", "executor"), [
    ("fusionripper-grid", "local-d0.5-f1.1-drive0", [], run_and_write_data),
    ("fusionripper-grid", "local-d0.5-f1.1-drive0", ["--figures-now"], run_and_write),
    ("table4", "ld3-start6", [], run_and_write),
    ("table4", "ld3-start6", ["--figures-later"], run_and_write_data),
])
def test_the_campaigns_choice_unless_a_flag_overrides_it(tmp_path, monkeypatch, name, run, flags, executor):
    seen = []
    monkeypatch.setattr(campaigns, "run_campaign", lambda runs, out, **kwargs: seen.append(kwargs["execute"]) or [])
    assert main(["campaign", name, "--runs", run, "--out", str(tmp_path), "--workers", "1", *flags]) == 0
    assert seen == [executor]
    report = (tmp_path / "report.md").read_text()
    assert (f"`ld3 figures {tmp_path}` draws them" in report) == (executor is run_and_write_data)
