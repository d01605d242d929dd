"""The worst-case attack search: the optimiser on a toy objective, determinism by seed, resume after a kill,
refusals, and end to end on a few closed-loop trials whose best.toml replays to the same figures."""

import csv
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from testbed.attacks.spec import attack_spec_to_dict
from testbed.attacks.threat import parse_threat
from testbed.errors import UserError
from testbed.eval.run.scenario import load_scenario
from testbed.eval.search import attack_search
from testbed.eval.search.attack_search import (
    CRASH_BONUS_M,
    AttackSearch,
    SearchSpec,
    attack_spec,
    families_for,
    is_loss,
    outcome_of,
    score,
)
from testbed.eval.search.report import write_search_report
from tests.eval.run.summary_helpers import fake_summary
from tests.eval.search.search_helpers import toy_executor, toy_search, toy_spec

ROOT = Path(__file__).resolve().parents[3]


def _rows(out: Path) -> list[dict[str, str]]:
    with (out / "trials.csv").open() as fh:
        return list(csv.DictReader(fh))


def test_the_search_finds_the_toy_optimum_and_reports_it(tmp_path):
    search = toy_search(tmp_path / "s", budget=40)
    outcomes = search.run()
    assert len(outcomes) == 40 and len(_rows(tmp_path / "s")) == 40
    best = search.best()
    assert best.family == "offmap" and best.dev_before_m > 2.7 and best.undetected_departure
    report = write_search_report(search)
    text = report.read_text()
    assert "offmap" in text and "Replay: `ld3 run" in text and (tmp_path / "s" / "convergence.png").stat().st_size
    assert "distance" in (tmp_path / "s" / "best.toml").read_text()


def test_the_same_seed_gives_the_same_trials_and_another_seed_others(tmp_path):
    a, b, c = (toy_search(tmp_path / n, budget=12, seed=s) for n, s in (("a", 3), ("b", 3), ("c", 4)))
    for s in (a, b, c):
        s.run()
    attacks = [[r["attack"] for r in _rows(tmp_path / n)] for n in "abc"]
    assert attacks[0] == attacks[1] and attacks[0] != attacks[2]


class _AskedFirst(attack_search.BatchAsker):
    """The whole batch asked before its first trial runs (the search's order before the asks overlapped runs)."""

    def __init__(self, *args) -> None:
        super().__init__(*args)
        self.join()


def test_a_batch_asked_while_its_trials_run_gives_the_trials_of_one_asked_first(tmp_path, monkeypatch):
    toy_search(tmp_path / "overlapped", budget=28, batch=8).run()
    monkeypatch.setattr(attack_search, "BatchAsker", _AskedFirst)
    toy_search(tmp_path / "first", budget=28, batch=8).run()
    assert (tmp_path / "overlapped" / "trials.csv").read_bytes() == (tmp_path / "first" / "trials.csv").read_bytes()
    assert len(_rows(tmp_path / "first")) == 28


def test_a_batchs_first_trial_runs_before_its_last_is_asked(tmp_path, monkeypatch):
    asked_at, started_at = [], []
    sample = attack_search.sample_attack

    def slow_sample(*args):
        time.sleep(0.05)
        attack = sample(*args)
        asked_at.append(time.monotonic())
        return attack

    def timed_executor(run, run_dir):
        started_at.append(time.monotonic())
        return toy_executor(run, run_dir)

    monkeypatch.setattr(attack_search, "sample_attack", slow_sample)
    search = toy_search(tmp_path / "s", budget=8, batch=8)
    search.execute = timed_executor
    search.run()
    assert len(asked_at) == len(started_at) == 8
    assert started_at[0] < asked_at[-1]  # the first trial did not wait for the whole batch's asks
    assert all(start > asked for start, asked in zip(started_at, asked_at, strict=True))


def test_attack_starts_follow_the_drive_when_the_road_ends_before_the_duration(tmp_path):
    # parking-lot: 80 m, ended 30 m before its end, from s = 5 at 4 m/s: the drive lasts 11.25 s at the least
    victim = load_scenario("parking-lot").replace(defense="ld3", localization="msf", duration=45.0)
    spec = SearchSpec(victim, parse_threat("msf-output"), 24, batch=8)
    assert spec.latest_start == pytest.approx(11.25 - 5.0)
    outcomes = AttackSearch(spec, tmp_path / "s", workers=1, progress=False, execute=toy_executor).run()
    starts = [float(o.attack["start"]) for o in outcomes if "start" in o.attack and o.family != "zone"]
    assert len(starts) > 12 and all(6.25 / 2 <= t <= 6.25 for t in starts)  # START's 8–30 s, scaled
    assert all(0.0 <= o.attack["start"] <= 6.25 for o in outcomes if o.family == "zone")  # its own 0–30 s
    with pytest.raises(UserError, match=r"reaches the road's end 2\.5 s in at 4 m/s"):
        SearchSpec(victim.replace(start_s=40.0), parse_threat("msf-output"), 4)


def test_a_trials_attack_spec_reads_back_as_its_table():
    table = {"kind": "bound-replay", "start": 22.6321, "scale": 0.9187, "cancel": True, "direction": "left"}
    assert attack_spec_to_dict(attack_spec(table)) == table


def test_a_killed_search_resumes_to_the_trials_of_an_uninterrupted_one(tmp_path):
    toy_search(tmp_path / "whole", budget=16).run()
    out = tmp_path / "killed"
    env = {**os.environ, "TOY_SLEEP_S": "0.15",
           "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.Popen([sys.executable, "-m", "tests.eval.search.search_helpers", str(out), "16"], cwd=ROOT,
                            env=env)
    try:
        deadline = time.monotonic() + 120.0
        while len(list((out / "trials").glob("trial-*"))) < 6:  # mid second batch of four
            assert proc.poll() is None and time.monotonic() < deadline, "the search never got under way"
            time.sleep(0.02)
        proc.send_signal(signal.SIGKILL)
    finally:
        proc.kill()
        proc.wait()
    assert len(_rows(out)) < 16
    resumed = toy_search(out, budget=16)
    resumed.run()
    assert _rows(out) == _rows(tmp_path / "whole")


def test_a_larger_budget_continues_and_another_search_is_refused(tmp_path):
    toy_search(tmp_path / "s", budget=4).run()
    toy_search(tmp_path / "s", budget=8).run()
    assert [r["trial"] for r in _rows(tmp_path / "s")] == [str(i) for i in range(8)]
    with pytest.raises(UserError, match="different search"):
        toy_search(tmp_path / "s", budget=8, seed=9)
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "x.txt").write_text("mine")
    with pytest.raises(UserError, match="not empty"):
        toy_search(tmp_path / "other", budget=4)


def test_a_told_trial_whose_summary_is_corrupt_is_named_and_its_reason_recorded(tmp_path, capsys):
    toy_search(tmp_path / "s", budget=4).run()
    (tmp_path / "s" / "trials" / "trial-0002" / "summary.json").write_text("{\"detected\": tru")
    capsys.readouterr()
    toy_search(tmp_path / "s", budget=4).run()
    err = capsys.readouterr().err
    assert "trial 2 was told but trials/trial-0002: summary.json unreadable (JSONDecodeError" in err
    rows = _rows(tmp_path / "s")
    assert rows[2]["consequence"] == "run_failed" and "summary.json unreadable" in rows[2]["failure"]
    assert [r["failure"] for i, r in enumerate(rows) if i != 2] == ["", "", ""]


def test_a_trial_whose_run_fails_records_the_failure(tmp_path):
    def failing(run, run_dir):
        raise RuntimeError("boom")

    search = AttackSearch(toy_spec(2), tmp_path / "s", workers=1, progress=False, execute=failing)
    search.run()
    assert [r["failure"] for r in _rows(tmp_path / "s")] == ["RuntimeError: boom"] * 2


def test_families_follow_the_threat_model_and_the_victim():
    victim = load_scenario("local").with_overrides(defense="ld3", localization="msf")
    names = {c.name for c in families_for(parse_threat("msf-output"), victim)}
    assert {"zone", "offmap", "burst", "stealthy", "trace"} <= names and "fusionripper" not in names
    assert {c.name for c in families_for(parse_threat("gnss"), victim)} == {"fusionripper", "gnss-drift"}
    both = {c.name for c in families_for(parse_threat("msf-output,ld-output"), victim)}
    assert "coordinated" in both and "drp-trace" in both
    with pytest.raises(UserError, match="localization that fuses GNSS"):
        families_for(parse_threat("gnss"), load_scenario("local"))
    with pytest.raises(UserError, match="budget"):
        SearchSpec(victim, parse_threat("gnss"), 0)


def test_score_puts_the_deviation_before_detection_first():
    undetected = fake_summary(detected=False, detection_dev_m=None, max_abs_dev_m=1.0)
    caught_late = fake_summary(detected=True, detection_dev_m=0.9, max_abs_dev_m=3.0)
    assert score(undetected, "undetected")[0] > score(caught_late, "undetected")[0]
    assert score(undetected, "overall")[0] < score(caught_late, "overall")[0]
    assert score(caught_late, "undetected")[1:] == (0.9, 3.0)
    crashed = fake_summary(detected=False, detection_dev_m=None, max_abs_dev_m=0.8, consequence="hit_curb")
    caught_crash = fake_summary(detected=True, detection_dev_m=0.9, max_abs_dev_m=3.0, consequence="hit_curb")
    caught_later = fake_summary(detected=True, detection_dev_m=1.2, max_abs_dev_m=3.0)
    assert score(crashed, "undetected")[0] > score(caught_later, "undetected")[0]
    assert score(caught_crash, "undetected")[0] == score(caught_late, "undetected")[0]
    assert score(caught_crash, "overall")[0] > score(caught_late, "overall")[0]


def test_loss_counts_any_departure_or_contact_detected_or_not_and_ranks_by_how_far():
    straddle = {"lane_straddle_dev_m": 0.7}
    stopped = {**straddle, "detected": True, "detection_dev_m": 0.3, "max_abs_dev_m": 0.45,
               "consequence": "stop_in_lane"}
    straddling = fake_summary(**{**stopped, "max_abs_dev_m": 0.75, "consequence": "stop_with_lane_straddle"})
    detected_crash = fake_summary(**{**stopped, "detection_dev_m": 0.1, "max_abs_dev_m": 0.9,
                                     "consequence": "hit_barrier"})
    undetected_crash = fake_summary(**straddle, detected=False, detection_dev_m=None, max_abs_dev_m=0.8,
                                    consequence="hit_curb")
    wide_but_reached = fake_summary(**straddle, detected=False, detection_dev_m=None, max_abs_dev_m=0.72,
                                    consequence="reach_destination")
    stopped = fake_summary(**stopped)
    assert not is_loss("stop_in_lane", 0.45, 0.7)
    assert is_loss("stop_with_lane_straddle", 0.5, 0.7) and is_loss("wrong_way", 0.1, 0.7)
    assert is_loss("reach_destination", 0.72, 0.7) and not is_loss("reach_destination", 0.72, None)
    scores = {k: score(v, "loss")[0] for k, v in {"stopped": stopped, "straddling": straddling,
                                                   "detected_crash": detected_crash, "undetected_crash":
                                                   undetected_crash, "wide": wide_but_reached}.items()}
    assert scores["stopped"] == pytest.approx(0.45 + 0.01 * 0.3)
    assert scores["straddling"] == pytest.approx(0.75 + 0.01 * 0.3 + CRASH_BONUS_M)
    # a detected crash is a loss like an undetected one, ranked by how far the car got
    assert scores["detected_crash"] > scores["undetected_crash"] > scores["straddling"] > scores["wide"]
    assert scores["wide"] > scores["stopped"]
    assert score(detected_crash, "undetected")[0] < score(undetected_crash, "undetected")[0]
    named = detected_crash.model_copy(update={"alarm_check": "heading-lines"})
    outcome = outcome_of(3, {"kind": "trace"}, named, "loss")
    assert outcome.loss is True and outcome.alarm_check == "heading-lines"
    assert outcome_of(4, {"kind": "trace"}, stopped, "loss").loss is False
    assert outcome_of(5, {"kind": "trace"}, None, "loss").loss is None
    assert SearchSpec(load_scenario("local").with_overrides(defense="ld3", localization="msf", duration=45.0),
                      parse_threat("msf-output"), 1).objective == "loss"


@pytest.mark.timeout(900)
def test_a_few_closed_loop_trials_and_their_best_replays(tmp_path):
    from testbed.eval.run.runner import run_scenario
    from testbed.eval.run.scenario import load_scenario as load

    victim = load_scenario("local").with_overrides(defense="ld3", localization="msf", duration=14.0)
    search = AttackSearch(SearchSpec(victim, parse_threat("msf-output"), 2, seed=1, batch=2), tmp_path / "s",
                          workers=1, progress=False)
    outcomes = search.run()
    assert len(outcomes) == 2 and all(o.score is not None for o in outcomes)
    write_search_report(search)
    best = search.best()
    replay = run_scenario(load(str(tmp_path / "s" / "best.toml")), tmp_path / "replay").summary
    assert replay["detected"] == best.detected and replay["consequence"] == best.consequence
    assert replay["max_abs_dev_m"] == pytest.approx(best.max_dev_m, abs=1e-9)
    assert replay["threat_model"] == "msf-output"


def test_a_tiny_sampled_bend_stays_a_non_zero_bend_the_attack_builds():
    import optuna

    from testbed.attacks.spec import parse_attack

    params = {"family": "drp-bend", "drp-bend.start": 20.0, "drp-bend.shift": -0.5, "drp-bend.bend": 3e-5,
              "drp-bend.ramp": 1.3, "drp-bend.duration": 6.5}
    table = attack_search.sample_attack(optuna.trial.FixedTrial(params), families_for(
        parse_threat("ld-output"), load_scenario("highway").with_overrides(defense="ld3", localization="msf")), 40.0)
    assert table["bend"] == 1e-4  # round(3e-5, 4) is 0.0, which drp-bend refuses
    assert parse_attack(attack_spec(table)).describe()["bend"] == 1e-4
    assert attack_search.spec_value(-3e-5) == -1e-4 and attack_search.spec_value(0.0) == 0.0
    assert attack_search.spec_value(29.68034) == 29.6803
