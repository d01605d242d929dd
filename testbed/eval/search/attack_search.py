"""Worst-case attack search (`ld3 search`): an optimiser over the attack families a threat model allows.

Each trial samples a family (an attack registry entry with a search space whose capabilities lie within the
threat model and whose needs the victim provides) and its parameters with Optuna's TPE sampler, runs the
victim scenario with that attack through the campaign machinery (`run_campaign`: local workers or Ray), and
scores it by what the attacker wants (`score`). Trials are asked in fixed batches whose sampler is seeded by
(seed, batch index), so the same seed gives the same trials whatever the number of workers, and a killed
search resumes from its journal (`study.log`): trials asked but not told are run (or read back) and told. A
batch's trials are asked in a thread (`BatchAsker`) while its first ones already run; none is told before the
batch ends.
"""

from __future__ import annotations

import csv
import functools
import json
import math
import queue
import sys
import threading
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import optuna
from optuna.trial import Trial, TrialState
from tqdm import tqdm

from testbed.attacks.registry import ATTACKS
from testbed.attacks.space import START, ChoiceDim, FloatDim, IntDim
from testbed.attacks.threat import ThreatCapability, threat_label, within_ld3_threat_model
from testbed.errors import UserError
from testbed.eval.campaign.driver import (
    CampaignRun,
    RunExecutor,
    RunQueue,
    campaign_backend,
    run_and_write_data,
    run_campaign,
    typed_summary,
)
from testbed.eval.run.consequence import Consequence
from testbed.eval.run.scenario import END_MARGIN_M, Scenario, check_needs
from testbed.eval.run.scenario_toml import scenario_document, write_scenario
from testbed.eval.run.summary import RunSummary
from testbed.eval.search.study_log import check_study_log
from testbed.registry import FIXES, Component, missing_needs
from tracks.presets import load_track

OBJECTIVES = ("loss", "undetected", "overall")
"""`loss` (the default): any lane departure or contact, detected or not, ranked by how far the car got (the
deviation reached at all, plus `CRASH_BONUS_M` for a loss); `undetected`: the physical deviation reached before
detection first, then the deviation reached at all; `overall`: the other way round."""
CRASHES = frozenset({Consequence.HIT_CURB, Consequence.HIT_BARRIER, Consequence.HIT_LANE_DIVIDER,
                     Consequence.FALL_OFF_ROAD, Consequence.OUT_OF_LANE, Consequence.WRONG_WAY,
                     Consequence.HIT_VEHICLE})
"""Consequences that end a drive in a collision or off its lane."""
LOSSES = CRASHES | {Consequence.STOP_WITH_LANE_STRADDLE}
"""Consequences that count as a loss for the defense: a collision, a departure, or a stop across a lane line."""
CRASH_BONUS_M = 1.0
"""Added to the score of a run that crashed (`undetected`: without a detection first): a crash ends the run,
which caps the deviation it can show, yet it is the attacker's best outcome."""
SECONDARY_WEIGHT = 0.01
"""Weight of the second criterion in the score (the first counts fully): a tie-break, near lexicographic for
deviations of a few metres."""
STUDY = "search"
TRIALS_DIR = "trials"
FAILED = "run_failed"


@dataclass(frozen=True)
class SearchSpec:
    """One search: the victim (its attack is what the search sets), the threat model, the trial budget, the
    seed of the sampler, the batch of trials asked at once, and the objective."""

    victim: Scenario
    threat: frozenset[ThreatCapability]
    budget: int
    seed: int = 0
    batch: int = 8
    objective: str = "loss"

    def __post_init__(self) -> None:
        if self.budget < 1:
            raise UserError(f"--budget must be >= 1 trial, got {self.budget}")
        if self.batch < 1:
            raise UserError(f"--batch must be >= 1, got {self.batch}")
        if self.seed < 0:
            raise UserError(f"--seed must be >= 0, got {self.seed}")
        if self.victim.duration < START.low + START_SLACK_S:
            raise UserError(f"the victim's run lasts {self.victim.duration} s; a search needs at least "
                            f"{START.low + START_SLACK_S} s so that its attacks start in time: --set duration=45")
        if self.latest_start < MIN_LATEST_START_S:
            raise UserError(f"the victim's drive reaches the road's end {self.latest_start + START_SLACK_S:.1f} s "
                            f"in at {self.victim.speed:g} m/s; a search needs at least "
                            f"{MIN_LATEST_START_S + START_SLACK_S:g} s: a lower start_s or speed")
        if self.objective not in OBJECTIVES:
            raise UserError(f"objective must be one of {', '.join(OBJECTIVES)}, got {self.objective!r}")

    @functools.cached_property
    def latest_start(self) -> float:
        """The latest attack start (s): `START_SLACK_S` before the victim's drive ends, at its duration or sooner at
        the road's end, reached at the earliest at cruise speed (the car never drives faster)."""
        track = load_track(self.victim.track)
        to_end = (track.length - END_MARGIN_M - self.victim.start_s) / self.victim.speed
        return min(self.victim.duration, to_end) - START_SLACK_S

    def identity(self) -> dict[str, Any]:
        """What must match for a search folder to be resumed (the budget may grow)."""
        return {"victim": scenario_document(self.victim), "threat": threat_label(self.threat), "seed": self.seed,
                "batch": self.batch, "objective": self.objective}


@dataclass(frozen=True)
class TrialOutcome:
    """What one trial's run gave the attacker (None figures for a run that failed)."""

    number: int
    family: str
    attack: dict[str, Any]
    detected: bool | None
    detection_time_s: float | None
    dev_before_m: float | None
    max_dev_m: float | None
    consequence: str
    straddle_m: float | None
    score: float | None
    failure: str = ""
    """Why a trial counts as `run_failed` (its run's failure, or what is wrong with its summary.json); else empty."""
    alarm_check: str | None = None
    """The defense's check that raised the alarm (summary.json's `alarm_check`); None without one."""

    @property
    def undetected_departure(self) -> bool:
        """The car reached the lane straddle deviation before any detection."""
        return (self.dev_before_m is not None and self.straddle_m is not None
                and self.dev_before_m >= self.straddle_m)

    @property
    def loss(self) -> bool | None:
        """The defense lost, detected or not (`is_loss`); None for a run that failed."""
        if self.score is None:
            return None
        return is_loss(self.consequence, self.max_dev_m, self.straddle_m)


def is_loss(consequence: str, max_dev_m: float | None, straddle_m: float | None) -> bool:
    """A collision or departure (`LOSSES`), or the car's centre reaching the lane straddle deviation."""
    return consequence in LOSSES or (max_dev_m is not None and straddle_m is not None and max_dev_m >= straddle_m)


def families_for(threat: frozenset[ThreatCapability], victim: Scenario) -> list[Component]:
    """The searchable attack families the threat model allows and the victim lets act; UserError, naming
    what is missing, when there are none."""
    provided = check_needs(victim.replace(attack=None))
    allowed, refused, unsearchable = [], [], []
    for component in ATTACKS:
        if not component.capabilities <= {c.value for c in threat}:
            continue
        if not component.space:
            unsearchable.append(f"{component.name} declares no search space")
            continue
        missing = missing_needs(component, provided)
        (refused if missing else allowed).append((component, missing))
    if not allowed:
        why = "; ".join([f"{c.name} needs {FIXES[m[0]]}" for c, m in refused] + unsearchable)
        raise UserError(f"no searchable attack family acts under threat model {threat_label(threat)} on this "
                        f"victim" + (f": {why}" if why else ""))
    return [c for c, _ in allowed]


START_SLACK_S = 5.0
"""An attack starts at least this long before the victim's drive ends (the search clips `start` ranges to it)."""
MIN_LATEST_START_S = 2.0
"""A victim whose drive leaves no attack start this late is refused."""


SPEC_DECIMALS = 4
"""Decimal places of a sampled real parameter in the trial's attack spec."""


def spec_value(draw: float) -> float:
    """`draw` rounded to `SPEC_DECIMALS` places, away from zero where it would round to zero: a small draw stays the
    sign of a non-zero value (an attack may refuse zero, as `drp-bend`'s bend does)."""
    value = round(draw, SPEC_DECIMALS)
    return value if value != 0.0 or draw == 0.0 else math.copysign(10.0 ** -SPEC_DECIMALS, draw)


def sample_attack(trial: Trial, families: Sequence[Component], latest_start: float) -> dict[str, Any]:
    """One attack table: the family, then each dimension of its space (named `family.parameter`); start times
    end at `latest_start` and begin no later than half of it (a drive too short for the family's range)."""
    component = next(c for c in families
                     if c.name == trial.suggest_categorical("family", [f.name for f in families]))
    table: dict[str, Any] = {"kind": component.name}
    for dim in component.space:
        key = f"{component.name}.{dim.name}"
        if isinstance(dim, FloatDim):
            low, high = dim.low, dim.high
            if dim.name == "start":
                high = min(high, latest_start)
                low = min(low, high / 2)
            table[dim.name] = spec_value(trial.suggest_float(key, low, high, log=dim.log))
        elif isinstance(dim, IntDim):
            table[dim.name] = trial.suggest_int(key, dim.low, dim.high)
        elif isinstance(dim, ChoiceDim):
            table[dim.name] = trial.suggest_categorical(key, list(dim.choices))
    return table


def score(summary: RunSummary, objective: str) -> tuple[float, float, float]:
    """(score, deviation before detection, deviation at all) of a run's summary, in metres: the first criterion
    plus `SECONDARY_WEIGHT` × the second, plus `CRASH_BONUS_M` for a crash (undetected, for `undetected`; any
    loss of `is_loss`, for `loss`)."""
    dev_all = float(summary.max_abs_dev_m or 0.0)
    detected = summary.detected
    before = summary.detection_dev_m if detected else dev_all
    dev_before = float(before if before is not None else 0.0)
    first, second = (dev_before, dev_all) if objective == "undetected" else (dev_all, dev_before)
    consequence = str(summary.consequence)
    if objective == "loss":
        lost = is_loss(consequence, dev_all, summary.lane_straddle_dev_m)
    else:
        lost = consequence in CRASHES and (objective == "overall" or not detected)
    return first + SECONDARY_WEIGHT * second + (CRASH_BONUS_M if lost else 0.0), dev_before, dev_all


def outcome_of(number: int, attack: dict[str, Any], summary: RunSummary | None, objective: str,
               failure: str = "") -> TrialOutcome:
    """A trial's outcome from its run's summary (None: the run failed, for the reason `failure`)."""
    if summary is None:
        return TrialOutcome(number, attack["kind"], attack, None, None, None, None, FAILED, None, None,
                            failure or "the run failed")
    value, dev_before, dev_all = score(summary, objective)
    return TrialOutcome(number, attack["kind"], attack, summary.detected, summary.detection_time_s,
                        dev_before, dev_all, str(summary.consequence), summary.lane_straddle_dev_m, value,
                        alarm_check=summary.alarm_check)


def trial_id(number: int) -> str:
    """A trial's run id and folder name under `trials/`."""
    return f"trial-{number:04d}"


def attack_spec(attack: dict[str, Any]) -> str:
    """The attack table as an `--attack` spec string."""
    args = ",".join(f"{k}={v}" for k, v in attack.items() if k != "kind")
    return f"{attack['kind']}:{args}" if args else attack["kind"]


class AttackSearch:
    """A resumable search in `out` (module docstring): `run()` completes the budget and returns the outcomes."""

    def __init__(self, spec: SearchSpec, out: Path, *, workers: int | None = None, backend: str = "local",
                 address: str | None = None, timeout: float | None = None, progress: bool = True,
                 execute: RunExecutor = run_and_write_data) -> None:
        """`execute` runs one trial's scenario into its folder (the campaign executor; the default writes the
        standard run outputs but the figures, which `ld3 figures` draws later)."""
        self.spec, self.out, self.execute = spec, out, execute
        self.workers, self.backend, self.address, self.timeout = workers, backend, address, timeout
        self.progress = progress
        self.families = families_for(spec.threat, spec.victim)
        self._check_folder()
        optuna.logging.set_verbosity(optuna.logging.WARNING)
        self.storage = optuna.storages.JournalStorage(
            optuna.storages.journal.JournalFileBackend(str(out / "study.log")))
        self.outcomes: dict[int, TrialOutcome] = {}

    def _check_folder(self) -> None:
        if self.out.exists() and not self.out.is_dir():
            raise UserError(f"--out {self.out} is a file; name a folder for the search")
        self.out.mkdir(parents=True, exist_ok=True)
        meta = self.out / "search.json"
        identity = self.spec.identity()
        if meta.exists():
            try:
                stored = json.loads(meta.read_text())
            except ValueError:
                raise UserError(f"{meta} is unreadable; remove the folder or choose another --out") from None
            if stored != json.loads(json.dumps(identity)):
                raise UserError(f"{self.out} holds a different search (victim, threat, seed, batch or objective); "
                                f"choose another --out")
            check_study_log(self.out / "study.log")
        elif any(self.out.iterdir()):
            raise UserError(f"--out {self.out} is not empty and holds no search; choose an empty or new folder")
        else:
            meta.write_text(json.dumps(identity, indent=2) + "\n")

    def _study(self, batch_index: int) -> optuna.Study:
        sampler = optuna.samplers.TPESampler(seed=self.spec.seed * 1_000_003 + batch_index, multivariate=True,
                                             group=True, constant_liar=True, n_startup_trials=min(16, self.spec.budget))
        return optuna.create_study(study_name=STUDY, storage=self.storage, direction="maximize", sampler=sampler,
                                   load_if_exists=True)

    def _scenario(self, number: int, attack: dict[str, Any]) -> Scenario:
        return self.spec.victim.replace(name=trial_id(number), attack=attack)

    def run(self) -> list[TrialOutcome]:
        """Run trials until `budget` have been told; write trials.csv after every batch. The backend's workers
        stay from batch to batch (`kept_warm`)."""
        with warnings.catch_warnings(), campaign_backend(self.backend, self.address).kept_warm():
            warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
            study = self._study(0)
            self._read_told(study)
            latest_start = self.spec.latest_start
            bar = tqdm(total=self.spec.budget, initial=len(self.outcomes), desc="search", unit="trial",
                       disable=not self.progress)
            pending = [t for t in study.get_trials(deepcopy=False) if t.state == TrialState.RUNNING]
            while True:
                if pending:
                    asked = [(t.number, t.user_attrs["attack"]) for t in pending]
                    pending = []
                    finished = self._run_batch(study, [self._run(n, attack) for n, attack in asked], asked)
                else:
                    n = len(study.get_trials(deepcopy=False))
                    size = min(self.spec.batch, self.spec.budget - n)
                    if size <= 0:
                        break
                    study = self._study(n // self.spec.batch)
                    asker = BatchAsker(study, self.families, latest_start, size)
                    try:
                        runs = RunQueue([trial_id(k) for k in range(n, n + size)],
                                        lambda run_id, asker=asker: self._run(*asker.take(run_id)))
                        finished = self._run_batch(study, runs, asker.asked)
                    finally:
                        asker.join()
                bar.update(len(finished))
                best = max((o.score for o in self.outcomes.values() if o.score is not None), default=None)
                if best is not None:
                    bar.set_postfix(best=f"{best:.2f}")
                self.write_trials()
            bar.close()
        self.write_trials()
        return self.sorted_outcomes()

    def _read_told(self, study: optuna.Study) -> None:
        for t in study.get_trials(deepcopy=False):
            if t.state in (TrialState.COMPLETE, TrialState.FAIL):
                summary = typed_summary(self.out / TRIALS_DIR / trial_id(t.number))
                failure = ""
                if isinstance(summary, str):
                    failure = f"{TRIALS_DIR}/{trial_id(t.number)}: {summary}"
                    if t.state == TrialState.COMPLETE:
                        print(f"{self.out.name}: trial {t.number} was told but {failure}; it counts as {FAILED}",
                              file=sys.stderr)
                self.outcomes[t.number] = outcome_of(t.number, t.user_attrs["attack"],
                                                     summary if isinstance(summary, RunSummary) else None,
                                                     self.spec.objective, failure)

    def _run(self, number: int, attack: dict[str, Any]) -> CampaignRun:
        """Trial `number`'s campaign run."""
        return CampaignRun(trial_id(number), self._scenario(number, attack),
                           {"trial": number, "family": attack["kind"]})

    def _run_batch(self, study: optuna.Study, runs: list[CampaignRun] | RunQueue,
                   asked: list[tuple[int, dict[str, Any]]]) -> list[TrialOutcome]:
        """Run the batch's trials and tell the sampler each one's score; `asked` holds (number, attack) of every
        trial once `runs` has run (a `RunQueue` fills it as its runs are made)."""
        done = {run.run_id: summary for run, summary in
                run_campaign(runs, self.out / TRIALS_DIR, workers=self.workers, progress=False, execute=self.execute,
                             timeout=self.timeout, backend=self.backend, address=self.address)}
        failures = failure_headers(self.out / TRIALS_DIR / "failures.txt")
        finished = []
        for n, attack in asked:
            outcome = outcome_of(n, attack, done.get(trial_id(n)), self.spec.objective,
                                 failures.get(trial_id(n), ""))
            if outcome.score is None:
                study.tell(n, state=TrialState.FAIL)
            else:
                study.tell(n, outcome.score)
            self.outcomes[n] = outcome
            finished.append(outcome)
        return finished

    def sorted_outcomes(self) -> list[TrialOutcome]:
        return [self.outcomes[n] for n in sorted(self.outcomes)]

    def best(self) -> TrialOutcome | None:
        scored = [o for o in self.sorted_outcomes() if o.score is not None]
        return max(scored, key=lambda o: (o.score, -o.number)) if scored else None

    def write_trials(self) -> Path:
        """trials.csv: one row per told trial."""
        path = self.out / "trials.csv"
        with path.open("w", newline="") as fh:
            writer = csv.writer(fh)
            writer.writerow(["trial", "family", "attack", "detected", "detection_time_s", "dev_before_detection_m",
                             "max_abs_dev_m", "consequence", "undetected_departure", "loss", "score", "failure",
                             "alarm_check"])
            for o in self.sorted_outcomes():
                writer.writerow([o.number, o.family, attack_spec(o.attack), csv_cell(o.detected),
                                 csv_cell(o.detection_time_s), csv_cell(o.dev_before_m), csv_cell(o.max_dev_m),
                                 o.consequence, csv_cell(o.undetected_departure), csv_cell(o.loss), csv_cell(o.score),
                                 o.failure, csv_cell(o.alarm_check)])
        return path

    def write_best(self) -> Path | None:
        """best.toml: the best trial's scenario, which `ld3 run` replays to the same figures."""
        best = self.best()
        if best is None:
            return None
        path = self.out / "best.toml"
        sc = self._scenario(best.number, best.attack).replace(name="search-best")
        write_scenario(path, sc, f"Worst attack found by ld3 search (trial {best.number}): "
                                 f"{attack_spec(best.attack)}\nReplay: ld3 run {path}")
        return path


class BatchAsker:
    """A batch's trials asked of the sampler in a thread, in order and as fast as it answers, while the first
    ones already run: `take` hands each to the campaign when a worker is free for it. The asks are the same, in
    the same order, as when the whole batch is asked first (the sampler sees no result of the batch before its
    end either way), so the trials are the same."""

    def __init__(self, study: optuna.Study, families: Sequence[Component], latest_start: float, size: int) -> None:
        self.asked: list[tuple[int, dict[str, Any]]] = []
        self._ready: queue.SimpleQueue[tuple[int, dict[str, Any]] | BaseException] = queue.SimpleQueue()
        self._thread = threading.Thread(target=self._ask, args=(study, families, latest_start, size),
                                        name="search-ask")
        self._thread.start()

    def _ask(self, study: optuna.Study, families: Sequence[Component], latest_start: float, size: int) -> None:
        try:
            for _ in range(size):
                trial = study.ask()
                attack = sample_attack(trial, families, latest_start)
                trial.set_user_attr("attack", attack)
                self._ready.put((trial.number, attack))
        except BaseException as exc:  # handed to the campaign process's thread by `take`
            self._ready.put(exc)

    def take(self, run_id: str) -> tuple[int, dict[str, Any]]:
        """The next trial asked, (number, attack), waiting for it if need be; its id must be `run_id`."""
        item = self._ready.get()
        if isinstance(item, BaseException):
            raise item
        if trial_id(item[0]) != run_id:
            raise RuntimeError(f"the sampler numbered a trial {trial_id(item[0])}, expected {run_id}: another "
                               f"process writes the same study.log")
        self.asked.append(item)
        return item

    def join(self) -> None:
        """Wait for the asks to end (they never wait on the campaign)."""
        self._thread.join()


def failure_headers(path: Path) -> dict[str, str]:
    """Run id → its failure's first line (`ErrorType: message`) from a campaign's `failures.txt`, if any."""
    if not path.exists():
        return {}
    lines = path.read_text(errors="replace").splitlines()
    return dict(line.split(": ", 1) for line in lines if line and not line[0].isspace() and ": " in line)


def csv_cell(value: Any) -> str:
    """A CSV cell: empty for None or NaN, lower-case booleans, floats to four decimals."""
    if value is None:
        return ""
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, float):
        return "" if math.isnan(value) else f"{value:.4f}"
    return str(value)


def in_threat_model_note(threat: frozenset[ThreatCapability]) -> str:
    """One line saying whether the threat model is one LD3 claims to defend against."""
    if within_ld3_threat_model(threat):
        return (f"threat model {threat_label(threat)}: within LD3's claims (the attacker controls one source: the "
                f"localization, paper §3, or the lane detector, §6.2)")
    return (f"threat model {threat_label(threat)}: outside LD3's threat model (the attacker controls both the "
            f"localization and lane-detection inputs); reported, not counted against LD3's design")

