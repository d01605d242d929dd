"""Campaign backends: choosing one from the CLI, the registry and a third-party backend added by entry point,
the Ray backend's equivalence with the local one (same seed, same bytes), its failure handling and its quick
refusal of a dead cluster address; `ld3 campaign list`."""

import json
import os
import socket
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from testbed import cli
from testbed.eval.campaign.backend import BackendUnavailable
from testbed.eval.campaign.cost import WALL_PER_SIM_S_CAMERA, WALL_PER_SIM_S_NO_CAMERA, campaign_cost, human_duration
from testbed.eval.campaign.driver import CAMPAIGN_BACKENDS, CampaignRun, run_campaign
from testbed.eval.experiments.campaigns import CAMPAIGNS
from testbed.eval.run.scenario import load_scenario
from tests.eval.campaign.campaign_helpers import process_probe, slow_writer, thread_probe

WALL_FIELDS = ("wall_time_s", "real_time_factor")


def _table4_argv(tmp_path, *extra):
    return ["campaign", "table4", "--runs", "ld3-start6", "--out", str(tmp_path / "c"), *extra]


def test_the_ray_backend_without_ray_installed_is_one_line_naming_the_fix(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "ray", None)  # `import ray` raises ImportError
    assert cli.main(_table4_argv(tmp_path, "--backend", "ray")) == cli.EXIT_USAGE
    assert capsys.readouterr().err == ("ld3: error: the ray backend needs Ray, which is not installed: "
                                       "pip install '.[ray]'\n")
    assert not (tmp_path / "c").exists()


@pytest.mark.parametrize(("extra", "message"), [
    (("--address", "auto"), "a cluster address ('auto') needs the ray backend: add --backend ray"),
    (("--workers", "0"), "workers must be ≥ 1, got 0"),
])
def test_campaign_options_that_cannot_act_are_refused(tmp_path, capsys, extra, message):
    assert cli.main(_table4_argv(tmp_path, *extra)) == cli.EXIT_USAGE
    assert capsys.readouterr().err == f"ld3: error: {message}\n"
    assert not (tmp_path / "c").exists()


def test_an_unreachable_ray_cluster_is_one_line_and_runs_nothing(tmp_path, monkeypatch, capsys):
    ray = pytest.importorskip("ray")

    def refuse(**kwargs):
        raise ConnectionError("Could not find any running Ray instance.")

    monkeypatch.setattr(ray, "init", refuse)
    assert cli.main(_table4_argv(tmp_path, "--backend", "ray", "--address", "auto")) == cli.EXIT_USAGE
    assert capsys.readouterr().err == ("ld3: error: cannot connect to the Ray cluster at 'auto': Could not find any "
                                       "running Ray instance.\n")
    assert not (tmp_path / "c" / "ld3-start6").exists()


def _unused_loopback_port() -> int:
    """A loopback TCP port nothing listens on (bound once by the OS, then released)."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


@pytest.mark.parametrize("scheme", ["", "ray://"])
def test_a_dead_ray_address_is_refused_within_seconds_in_one_line(tmp_path, capsys, scheme):
    pytest.importorskip("ray")
    address = f"{scheme}127.0.0.1:{_unused_loopback_port()}"
    t0 = time.monotonic()
    assert cli.main(_table4_argv(tmp_path, "--backend", "ray", "--address", address)) == cli.EXIT_USAGE
    assert time.monotonic() - t0 < 10.0
    err = capsys.readouterr().err
    assert err.startswith(f"ld3: error: cannot connect to the Ray cluster at {address!r}: nothing answers at "
                          f"127.0.0.1:{address.rsplit(':', 1)[1]}")
    assert err.count("\n") == 1
    assert not (tmp_path / "c").exists()


def test_an_unreadable_ray_address_is_one_line(tmp_path):
    pytest.importorskip("ray")
    with pytest.raises(BackendUnavailable, match="cannot read the Ray cluster address 'ray://head:port'"):
        run_campaign([], tmp_path / "c", backend="ray", address="ray://head:port")
    assert not (tmp_path / "c").exists()


def test_an_unknown_backend_is_refused_naming_the_known_ones(tmp_path, capsys):
    runs = [CampaignRun("r", load_scenario("slr"), {})]
    with pytest.raises(ValueError, match=r"^unknown campaign backend 'slurm'; known: local, ray$"):
        run_campaign(runs, tmp_path / "c", backend="slurm")
    with pytest.raises(SystemExit):
        cli.main(_table4_argv(tmp_path, "--backend", "slurm"))
    error = capsys.readouterr().err.splitlines()[-1]
    assert "--backend: invalid choice: 'slurm'" in error and "'local', 'ray'" in error
    assert not (tmp_path / "c").exists()


PLUGIN = textwrap.dedent('''
    """A third-party campaign backend: runs in this process, newest first, and records the order."""
    from testbed.eval.campaign.backend import CampaignBackend, RunOutcome
    from testbed.eval.campaign.run import attempt_within, run_limit, temp_dir

    ORDER = []


    class Reversed(CampaignBackend):
        name = "reversed"
        help = "this process, last run first"

        def run(self, batch, out, execute, timeout, workers, address):
            for run in reversed(batch):
                ORDER.append(run.run_id)
                tmp = temp_dir(out, run.run_id)
                tmp.mkdir(parents=True)
                yield RunOutcome(run, attempt_within(execute, run, tmp, run_limit(run, timeout)))


    BACKEND = Reversed()
''')


@pytest.fixture
def backend_plugin(tmp_path, monkeypatch):
    """The plugin above installed (module and entry point) on sys.path for the test."""
    site = tmp_path / "site"
    info = site / "ld3_backendplugin-0.1.dist-info"
    info.mkdir(parents=True)
    (site / "ld3_backendplugin.py").write_text(PLUGIN)
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: ld3-backendplugin\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text("[ld3.campaign_backends]\nreversed = ld3_backendplugin:BACKEND\n")
    monkeypatch.syspath_prepend(str(site))
    CAMPAIGN_BACKENDS.reload_plugins()
    yield site
    monkeypatch.undo()
    CAMPAIGN_BACKENDS.reload_plugins()
    sys.modules.pop("ld3_backendplugin", None)


def test_a_backend_added_by_entry_point_runs_a_campaign_and_is_a_cli_choice(backend_plugin, tmp_path):
    from tests.eval.campaign.campaign_helpers import warning_writer

    assert CAMPAIGN_BACKENDS.names() == ("local", "ray", "reversed")
    runs = [CampaignRun(f"r{i}", load_scenario("slr"), {}) for i in range(3)]
    done = run_campaign(runs, tmp_path / "c", progress=False, execute=warning_writer, backend="reversed")
    assert [s.scenario for _, s in done] == ["r0", "r1", "r2"]
    assert sys.modules["ld3_backendplugin"].ORDER == ["r2", "r1", "r0"]
    assert not list((tmp_path / "c").glob(".*.tmp-*"))
    with pytest.raises(ValueError, match=r"a cluster address \('auto'\) needs the ray backend: add --backend ray"):
        run_campaign(runs, tmp_path / "d", backend="reversed", address="auto")
    parser = cli.build_parser()
    args = parser.parse_args(["campaign", "table4", "--backend", "reversed"])
    assert args.backend == "reversed"


def test_ld3_campaign_passes_backend_address_and_workers_through(tmp_path, monkeypatch):
    from testbed.eval.experiments import campaigns

    seen = {}

    def fake_run_campaign(runs, out, **kwargs):
        out.mkdir(parents=True, exist_ok=True)
        seen.update(kwargs)
        return []

    monkeypatch.setattr(campaigns, "run_campaign", fake_run_campaign)
    assert cli.main(_table4_argv(tmp_path, "--backend", "ray", "--address", "ray://head:10001")) == 0
    assert (seen["backend"], seen["address"], seen["workers"]) == ("ray", "ray://head:10001", None)
    assert cli.main(_table4_argv(tmp_path, "--workers", "3")) == 0
    assert (seen["backend"], seen["address"], seen["workers"]) == ("local", None, 3)


def test_campaign_list_shows_runs_simulated_and_estimated_time_of_every_campaign(capsys):
    assert cli.main(["campaign", "list", "--workers", "4"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert "est. wall (4 workers)" in lines[0]
    rows = {line.split()[0]: line.split() for line in lines[1:-1]}
    assert list(rows) == [spec.name for spec in CAMPAIGNS]
    grid = campaign_cost(CAMPAIGNS.get("fusionripper-grid").build("neural"))
    assert rows["fusionripper-grid"][1:4] == ["640", "8.9", "h"]  # 640 runs × 50 s
    assert " ".join(rows["fusionripper-grid"][4:6]) == human_duration(grid.wall_s(4))


def test_campaign_list_prints_only_its_table_and_loads_no_physics_engine():
    """pybullet writes its build time to stdout when it loads: listing campaigns must not load it."""
    probe = ("import sys; from testbed import cli; code = cli.main(['campaign', 'list']); "
             "sys.exit(code if 'pybullet' not in sys.modules else 99)")
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120,
                          cwd=Path(__file__).resolve().parents[3])
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines()[0].split()[:3] == ["campaign", "runs", "simulated"]


def test_campaign_list_refuses_options_it_would_ignore(capsys):
    assert cli.main(["campaign", "list", "--runs", "x*", "--backend", "ray"]) == cli.EXIT_USAGE
    assert capsys.readouterr().err == ("ld3: error: `ld3 campaign list` takes only --detector and --workers; "
                                       "drop --runs, --backend\n")


def test_the_cost_of_a_run_depends_on_whether_its_detector_reads_the_camera():
    sc = load_scenario("slr").with_overrides(duration=10.0)
    runs = [CampaignRun("neural", sc.with_overrides(detector="neural"), {}),
            CampaignRun("oracle", sc.with_overrides(detector="oracle"), {}),
            CampaignRun("none", sc.with_overrides(detector="none", duration=5.0), {})]
    cost = campaign_cost(runs)
    assert (cost.runs, cost.sim_s) == (3, 25.0)
    assert cost.wall_s(1) == pytest.approx(10.0 * WALL_PER_SIM_S_CAMERA + 15.0 * WALL_PER_SIM_S_NO_CAMERA)
    assert cost.wall_s(50) == cost.longest_run_s == pytest.approx(10.0 * WALL_PER_SIM_S_CAMERA)
    assert WALL_PER_SIM_S_CAMERA > WALL_PER_SIM_S_NO_CAMERA > 0


def test_local_workers_compute_on_one_thread_each_as_rays_do(tmp_path):
    runs = [CampaignRun(f"r{i}", load_scenario("slr"), {}) for i in range(2)]
    done = run_campaign(runs, tmp_path, workers=2, progress=False, execute=thread_probe)
    assert [s.attack_state["torch_threads"] for _, s in done] == [1, 1]


def test_the_same_run_is_byte_identical_on_the_local_and_the_ray_backend(tmp_path):
    pytest.importorskip("ray")
    sc = load_scenario("urban-straight").with_overrides(
        duration=3.0, detector="neural", localization="msf", defense="ld3",
        attack={"kind": "trace", "trace": "default", "start": 1.0})
    runs = [CampaignRun("attacked", sc, {}), CampaignRun("seed7", sc.with_overrides(seed=7, attack=None), {})]
    local = run_campaign(runs, tmp_path / "local", workers=1, progress=False)
    remote = run_campaign(runs, tmp_path / "ray", workers=2, progress=False, backend="ray")
    assert [r.run_id for r, _ in remote] == ["attacked", "seed7"]
    for (run, s_local), (_, s_ray) in zip(local, remote, strict=True):
        a, b = tmp_path / "local" / run.run_id, tmp_path / "ray" / run.run_id
        assert sorted(p.name for p in b.iterdir()) == sorted(p.name for p in a.iterdir())
        assert (b / "trajectory.csv").read_bytes() == (a / "trajectory.csv").read_bytes()
        assert (b / "birdseye.png").read_bytes() == (a / "birdseye.png").read_bytes()
        strip = [{k: v for k, v in s.model_dump(mode="json").items() if k not in WALL_FIELDS} for s in (s_local, s_ray)]
        assert strip[0] == strip[1] == {k: v for k, v in json.loads((b / "summary.json").read_text()).items()
                                        if k not in WALL_FIELDS}
    assert not list((tmp_path / "ray").glob(".*.tmp-*"))


def test_the_ray_backend_records_failures_timeouts_and_dead_workers_and_goes_on(tmp_path):
    ray = pytest.importorskip("ray")
    sc = load_scenario("slr")
    runs = [CampaignRun("hang", sc, {"hang": True}), CampaignRun("fail", sc, {"fail": True}),
            CampaignRun("die", sc, {"die": True}), *(CampaignRun(f"grp/ok{i}", sc, {"parts": 2}) for i in range(3))]
    ray.init(num_cpus=2, include_dashboard=False)  # a connection this process holds is used and left open
    try:
        done = run_campaign(runs, tmp_path, workers=2, progress=False, execute=slow_writer, timeout=8.0,
                            backend="ray")
        assert ray.is_initialized()
        with pytest.raises(ValueError, match="Ray is already connected in this process"):
            run_campaign(runs, tmp_path / "other", progress=False, execute=slow_writer, backend="ray",
                         address="auto")
    finally:
        ray.shutdown()
    assert [r.run_id for r, _ in done] == ["grp/ok0", "grp/ok1", "grp/ok2"]
    for i in range(3):
        assert {p.name for p in (tmp_path / "grp" / f"ok{i}").iterdir()} == {"summary.json", "part-0", "part-1"}
    headers = sorted(line for line in (tmp_path / "failures.txt").read_text().splitlines()
                     if not line.startswith(" "))
    assert headers[0].startswith("die: WorkerDied: ")
    assert headers[1:] == ["fail: RuntimeError: boom second line", "hang: RunTimeout: over its 8 s limit"]
    assert not list(tmp_path.rglob(".*.tmp-*"))
    assert not (tmp_path / "pids.log").exists()  # the workers wrote only into their scratch folders


@pytest.mark.slow
def test_a_ray_task_deaf_to_its_alarm_is_cancelled_after_the_start_allowance(tmp_path, monkeypatch):
    pytest.importorskip("ray")
    from testbed.eval.campaign import ray_backend

    monkeypatch.setattr(ray_backend, "START_ALLOWANCE_S", 30.0)
    sc = load_scenario("slr")
    runs = [CampaignRun("deaf", sc, {"deaf": True}), CampaignRun("ok", sc, {"parts": 1})]
    done = run_campaign(runs, tmp_path, workers=1, progress=False, execute=slow_writer, timeout=5.0,
                        backend="ray")
    assert [r.run_id for r, _ in done] == ["ok"]
    assert (tmp_path / "failures.txt").read_text() == ("deaf: RunTimeout: over its 5 s limit (+ 30 s to start, "
                                                       "cancelled)\n")
    assert not list(tmp_path.glob(".*.tmp-*"))


@pytest.mark.parametrize("path", sorted((Path(__file__).resolve().parents[3] / "docs" / "cluster").glob("*.yaml")),
                         ids=lambda p: p.name)
def test_the_documented_cluster_configs_pass_rays_schema(path):
    autoscaler = pytest.importorskip("ray.autoscaler")
    import jsonschema
    import yaml

    schema = json.loads((Path(autoscaler.__file__).parent / "ray-schema.json").read_text())
    jsonschema.validate(yaml.safe_load(path.read_text()), schema)


def test_ray_kept_warm_connects_once_for_every_batch_and_shuts_down_after(tmp_path, monkeypatch):
    ray = pytest.importorskip("ray")
    from testbed.eval.campaign.driver import campaign_backend

    inits = []
    real_init = ray.init
    monkeypatch.setattr(ray, "init", lambda *a, **k: inits.append(k) or real_init(*a, **k))
    sc = load_scenario("slr")

    def batch(name: str) -> set[int]:
        runs = [CampaignRun(f"{name}{i}", sc, {}) for i in range(4)]
        done = run_campaign(runs, tmp_path / name, workers=2, progress=False, execute=process_probe,
                            backend="ray")
        return {s.attack_state["pid"] for _, s in done}

    with campaign_backend("ray", None).kept_warm():
        first = batch("a")
        assert ray.is_initialized()
        second = batch("b")
    assert len(inits) == 1 and not ray.is_initialized()
    assert second <= first and os.getpid() not in first  # the second batch ran on the first's Ray workers
    batch("cold")
    assert len(inits) == 2 and not ray.is_initialized()  # outside: a connection per batch, as before
