"""`ld3 compare`'s report links each run's birdseye.png: a run that left its figures for later has them drawn."""

from testbed.eval.report.compare import compare_runs
from testbed.eval.run.figures import BIRDSEYE
from testbed.eval.run.runner import run_into
from testbed.eval.run.scenario import load_scenario


def test_a_run_that_left_its_figures_for_later_has_the_linked_one_drawn(tmp_path):
    sc = load_scenario("slr").with_overrides(duration=2.0, detector="oracle")
    (tmp_path / "later").mkdir()
    run_into(sc, tmp_path / "later", figures=False)
    assert not (tmp_path / "later" / BIRDSEYE).exists()
    report = compare_runs([tmp_path / "later"], tmp_path / "cmp").read_text()
    assert f"(../later/{BIRDSEYE})" in report and (tmp_path / "later" / BIRDSEYE).stat().st_size > 5000
