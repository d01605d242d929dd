"""The `ld3` command: run scenarios, inspect tracks, benchmarks, lane-detector tooling, campaigns, CAN.

Every user error (unknown preset, malformed TOML, unreachable speed, unwritable output) ends in one
line on stderr and exit status 2, never a traceback.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import signal
import sys
import threading
from collections.abc import Callable
from importlib.metadata import entry_points
from pathlib import Path
from typing import NoReturn

from testbed.errors import UserError, one_line

EXIT_USAGE = 2
PLUGIN_GROUP = "ld3.commands"  # packages that build on testbed (hil) add subcommands here; testbed imports none


DEMO_PATCH = "drp-patch:at=62,offset=-0.8,width=2,length=30,darkness=0.8,angle=-0.05"


def positive(text: str, what: str = "number") -> float:
    """A value for argparse: a finite number > 0 (`what` names it in the one-line error)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a {what}, got {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be a finite {what} > 0, got {text!r}")
    return value


def seconds(text: str) -> float:
    """A time limit for argparse: a finite number of seconds > 0."""
    return positive(text, "number of seconds")


class OneLineParser(argparse.ArgumentParser):
    """argparse that refuses bad arguments in one line pointing at --help (its sub-parsers too)."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _add_run_overrides(p: argparse.ArgumentParser) -> None:
    from testbed.attacks.registry import ATTACKS
    from testbed.defense.registry import DEFENSES
    from testbed.localization.registry import LOCALIZATIONS
    from testbed.perception.detectors.registry import DETECTORS

    p.add_argument("scenario", help="shipped scenario name (see `ld3 scenarios`) or path to a .toml file")
    p.add_argument("--track", help="track preset NAME[@SEED] or an OpenDRIVE route xodr:PATH[#ROAD,...][@LANE]")
    p.add_argument("--vehicle", help="vehicle parameter set (sedan, dev-chassis)")
    p.add_argument("--speed", type=float, help="target speed (m/s)")
    p.add_argument("--duration", type=float, help="simulated duration (s)")
    p.add_argument("--condition", help="day, dusk, night, rain, worn, shadows")
    p.add_argument("--seed", type=int, help="scenario seed (all random draws)")
    p.add_argument("--lane", type=int, help="ego lane index (0 = rightmost)")
    p.add_argument("--detector", choices=DETECTORS.names(), metavar="NAME",
                   help=f"lane detector: {DETECTORS.choices_help()}")
    p.add_argument("--localization", choices=LOCALIZATIONS.names(), metavar="NAME",
                   help=f"localization: {LOCALIZATIONS.choices_help()}")
    p.add_argument("--defense", choices=DEFENSES.names(), metavar="NAME", help=f"defense: {DEFENSES.choices_help()}")
    p.add_argument("--attack", action="append", default=[],
                   help="attack spec KIND[:key=value,...], e.g. trace:default or fusionripper:d=0.5,f=1.3; repeat it "
                        "to compose attacks (hooks run in the given order); "
                        f"kinds: {', '.join(ATTACKS.names())} (`ld3 components` lists their parameters)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scenario value as TOML would set it: defense.heading=msf, attack.start=12, "
                        "speed=10 (repeatable)")
    p.add_argument("--out", type=Path, help="output directory (default runs/<scenario>-<seed>)")
    p.add_argument("--force", action="store_true", help="replace a finished run already in --out")


def scenario_from_args(args: argparse.Namespace):
    from testbed.attacks.spec import specs_to_value
    from testbed.eval.run.scenario import apply_settings, load_scenario

    sc = load_scenario(args.scenario)
    attack = specs_to_value(getattr(args, "attack", None) or [])
    sc = sc.with_overrides(track=args.track, vehicle=args.vehicle, speed=args.speed, duration=args.duration,
                           condition=args.condition, seed=args.seed, lane=args.lane, detector=args.detector,
                           localization=args.localization, defense=args.defense, attack=attack)
    return apply_settings(sc, getattr(args, "set", []))


def cmd_run(args: argparse.Namespace) -> int:
    from testbed.attacks.spec import attack_tables
    from testbed.eval.run.folder import check_out_dir
    from testbed.eval.run.runner import run_scenario

    sc = scenario_from_args(args)
    out = args.out or Path("runs") / f"{sc.name}-{sc.seed}"
    check_out_dir(out, args.force)
    attack = "+".join(t["kind"] for t in attack_tables(sc.attack)) or "none"
    print(f"{sc.name} on {sc.track}: detector {sc.detector}, localization {sc.localization}, defense {sc.defense}, "
          f"attack {attack}, seed {sc.seed}")
    result = run_scenario(sc, out, video=args.video, record=args.record, progress=sys.stderr.isatty(),
                          force=args.force)
    s = result.summary
    print(f"{sc.name}: consequence {s['consequence']}, max |D| {s['max_abs_dev_m']:.3f} m, "
          f"detected {s['detected']}, {s['sim_time_s']:.1f} s simulated at {s['real_time_factor']:.1f}x real time")
    extra = [name for name, wanted in (("camera.mp4", args.video), ("run.mcap", args.record)) if wanted]
    print(f"outputs: {out}/" + ", ".join(["summary.json", "trajectory.csv", "birdseye.png", *extra]))
    return 0


def cmd_components(args: argparse.Namespace) -> int:
    from testbed.attacks.registry import ATTACKS
    from testbed.defense.registry import DEFENSES
    from testbed.eval.campaign.driver import CAMPAIGN_BACKENDS
    from testbed.eval.experiments.campaigns import CAMPAIGNS
    from testbed.eval.run.scenario_reference import reference_markdown
    from testbed.localization.registry import LOCALIZATIONS
    from testbed.perception.detectors.registry import DETECTORS
    from testbed.presets import TRACKS, VEHICLES

    for registry in (DEFENSES, DETECTORS, LOCALIZATIONS, ATTACKS, TRACKS, VEHICLES, CAMPAIGNS,
                     CAMPAIGN_BACKENDS):
        group = f" (plugins: entry-point group {registry.group})" if registry.group else ""
        print(f"## {registry.family}s{group}\n\n{registry.markdown()}\n")
    print(reference_markdown())
    return 0


def cmd_schema(args: argparse.Namespace) -> int:
    from testbed.eval.run.scenario_reference import json_schema

    text = json.dumps(json_schema(), indent=2) + "\n"
    if args.out is None:
        sys.stdout.write(text)
    else:
        from testbed.eval.run.folder import output_file

        with output_file(args.out) as tmp:
            tmp.write_text(text)
        print(f"wrote {args.out}")
    return 0


def cmd_compare(args: argparse.Namespace) -> int:
    from testbed.eval.report.compare import compare_runs
    from testbed.eval.run.folder import output_folder

    with output_folder(args.out, force=True, marker="report.md", what="a comparison") as tmp:
        compare_runs(args.runs, tmp)
    report = args.out / "report.md"
    print(report.read_text())
    print(f"report: {report} (plot: {args.out / 'deviations.png'})")
    return 0


def cmd_figures(args: argparse.Namespace) -> int:
    from testbed.eval.report.figures_later import draw_later, run_folders

    folders = run_folders(args.dir)
    drawn = [d for d in folders if draw_later(d)]
    print(f"figures drawn for {len(drawn)} of {len(folders)} run folders under {args.dir} (the others have "
          f"birdseye.png already, or no believed.csv to draw it from)")
    return 0


def cmd_scenarios(args: argparse.Namespace) -> int:
    from testbed.eval.run.scenario import load_scenario, shipped_scenarios

    for name in shipped_scenarios():
        sc = load_scenario(name)
        print(f"{name:16s} track {sc.track:16s} {sc.vehicle:12s} {sc.speed:5.1f} m/s  {sc.duration:5.0f} s")
    return 0


def cmd_tracks(args: argparse.Namespace) -> int:
    from testbed.eval.run.folder import output_file
    from testbed.presets import TRACKS, build_track
    from tracks.plot import save_track_png

    if args.tracks_cmd == "list":
        for component in TRACKS:
            print(f"{component.name:16s} {component.help}")
        return 0
    if args.tracks_cmd == "routes":
        from testbed.presets import xodr_routes

        for spec, roads, length in xodr_routes(args.file):
            print(f"{spec}  {roads} road(s), {length:.0f} m")
        return 0
    track = build_track(args.name)
    stem = re.sub(r"[^\w.-]+", "-", Path(args.name.removeprefix("xodr:")).name).strip("-")
    if args.tracks_cmd == "export":
        from tracks.opendrive.write import write_xodr

        out = args.out or Path(f"{stem}.xodr")
        with output_file(out) as tmp:
            write_xodr(track, tmp)
        print(f"wrote {out} ({track.description})")
        return 0
    out = args.out or Path(f"{stem}.png")
    with output_file(out, ".png") as tmp:
        save_track_png(track, tmp)
    print(f"wrote {out}")
    return 0


def cmd_patch_figure(args: argparse.Namespace) -> int:
    from testbed.attacks.spec import attack_spec_to_dict
    from testbed.eval.report.drp_figure import drp_before_after
    from testbed.eval.run.folder import output_file

    with output_file(args.out, ".png") as tmp:
        clean, patched = drp_before_after(tmp, attack_spec_to_dict(args.attack), args.track, args.detector,
                                          args.ahead)
    dev = ["none" if v.ld_dev is None else f"{v.ld_dev:+.3f} m" for v in (clean, patched)]
    print(f"D_LD clean {dev[0]}, with the patch {dev[1]}; wrote {args.out}")
    return 0


LOOP_ONLY = ("camera", "scenario", "speed", "localization", "ground", "detector", "seconds", "traffic", "settings")


def cmd_bench(args: argparse.Namespace) -> int:
    from testbed.eval.analysis import bench

    given = ["--set" if name == "settings" else f"--{name}" for name in LOOP_ONLY if getattr(args, name) is not None]
    if args.what != "loop" and given:
        raise UserError(f"{', '.join(given)} only apply to `ld3 bench loop`; drop them for `{args.what}`")
    loop = {name: getattr(args, name) for name in LOOP_ONLY if getattr(args, name) is not None}
    if "camera" in loop:
        loop["camera"] = loop["camera"] == "on"
    result = bench.run(args.what, **loop)
    print(json.dumps(result, indent=2) if args.json else format_bench(result))
    return 0


def format_bench(result: dict, indent: str = "") -> str:
    """A benchmark's result as indented `key: value` lines."""
    lines = []
    for key, value in result.items():
        if isinstance(value, dict):
            lines += [f"{indent}{key}:", format_bench(value, indent + "  ")]
        else:
            lines.append(f"{indent}{key}: {value}")
    return "\n".join(lines)


def cmd_demo(args: argparse.Namespace) -> int:
    from testbed.eval.experiments.demo import run_demo
    from testbed.eval.run.folder import output_folder

    with output_folder(args.out, force=True, marker="report.md", what="a demo") as tmp:
        run_demo(tmp, progress=sys.stderr.isatty())
    print(f"demo report: {args.out / 'report.md'}")
    return 0


def cmd_campaign(args: argparse.Namespace) -> int:
    from testbed.eval.campaign.driver import CAMPAIGN_BACKENDS, CampaignBusyError

    if args.name == "list":
        return _campaign_list(args)
    out = args.out or Path("runs") / f"campaign-{args.name}"
    # the workers start (and load the simulation) while this process loads the campaigns and builds the runs
    with CAMPAIGN_BACKENDS.get(args.backend or "local").kept_warm(args.workers, start=True):
        from testbed.eval.experiments.campaigns import run_named

        try:
            report = run_named(args.name, out, detector=args.detector, workers=args.workers,
                               progress=sys.stderr.isatty(), select=args.runs, settings=args.set,
                               timeout=args.timeout, backend=args.backend or "local", address=args.address,
                               attacks=args.attack, budget=args.budget, maps=args.maps,
                               figures=True if args.figures_now else False if args.figures_later else None)
        except CampaignBusyError as exc:
            raise UserError(str(exc)) from None
    print(report.read_text())
    print(f"report: {report}")
    return 0


def _campaign_list(args: argparse.Namespace) -> int:
    """`ld3 campaign list`: every campaign with its runs, simulated time and estimated wall time."""
    from testbed.eval.campaign.backend import DEFAULT_WORKERS
    from testbed.eval.campaign.cost import campaign_cost, human_duration
    from testbed.eval.experiments.campaigns import CAMPAIGNS

    unused = [flag for flag, value in (("--out", args.out), ("--timeout", args.timeout), ("--runs", args.runs),
                                       ("--set", args.set), ("--attack", args.attack), ("--backend", args.backend),
                                       ("--address", args.address), ("--budget", args.budget),
                                       ("--maps", args.maps), ("--figures-later", args.figures_later),
                                       ("--figures-now", args.figures_now))
              if value]
    if unused:
        raise UserError(f"`ld3 campaign list` takes only --detector and --workers; drop {', '.join(unused)}")
    workers = args.workers or DEFAULT_WORKERS
    print(f"{'campaign':18s} {'runs':>5s} {'simulated':>10s} {f'est. wall ({workers} workers)':>24s}  what")
    for spec in CAMPAIGNS:
        cost = campaign_cost(spec.build(args.detector))
        print(f"{spec.name:18s} {cost.runs:5d} {human_duration(cost.sim_s):>10s} "
              f"{human_duration(cost.wall_s(workers)):>24s}  {spec.help}")
    print(f"Estimated from the measured cost per simulated second on one core (lane detector {args.detector}); "
          "see docs/cluster.md.")
    return 0


def cmd_paper(args: argparse.Namespace) -> int:
    from testbed.eval.campaign.driver import CampaignBusyError
    from testbed.eval.experiments.paper import PaperOptions, run_paper

    options = PaperOptions(args.out, quick=args.quick, workers=args.workers, detector=args.detector,
                           timeout=args.timeout, progress=sys.stderr.isatty(), backend=args.backend,
                           address=args.address)
    try:
        report = run_paper(options, announce=lambda line: print(line, flush=True))
    except CampaignBusyError as exc:
        raise UserError(str(exc)) from None
    print(f"report: {report}")
    return 0


def cmd_search(args: argparse.Namespace) -> int:
    from concurrent.futures import ThreadPoolExecutor

    from testbed.attacks.threat import parse_threat
    from testbed.eval.campaign.driver import CAMPAIGN_BACKENDS

    # the workers start (and load the simulation) while this process prepares the search (bad input ends them at
    # once; the search checks the backend and the address); the report's bound is solved in a thread while the
    # trials run
    with CAMPAIGN_BACKENDS.get(args.backend).kept_warm(args.workers, start=True):
        from testbed.eval.search.attack_search import AttackSearch, SearchSpec
        from testbed.eval.search.report import search_bound, write_search_report

        victim = search_victim(args)
        spec = SearchSpec(victim, parse_threat(args.threat), args.budget, seed=args.search_seed, batch=args.batch,
                          objective=args.objective)
        search = AttackSearch(spec, args.out, workers=args.workers, backend=args.backend, address=args.address,
                              timeout=args.timeout, progress=sys.stderr.isatty())
        print(f"search on {victim.name} ({victim.track}): defense {victim.defense}, detector {victim.detector}, "
              f"localization {victim.localization}; threat {args.threat}; families "
              f"{', '.join(c.name for c in search.families)}; budget {args.budget}")
        with ThreadPoolExecutor(max_workers=1) as pool:
            bound = pool.submit(search_bound, victim)
            search.run()
    report = write_search_report(search, bound.result())
    best = search.best()
    if best is not None:
        print(f"worst attack: {best.attack['kind']} (trial {best.number}): detected {best.detected}, |D| before "
              f"detection {best.dev_before_m:.3f} m, max |D| {best.max_dev_m:.3f} m, {best.consequence}")
        print(f"replay: ld3 run {args.out / 'best.toml'}")
    print(f"report: {report}; every trial: {args.out / 'trials.csv'}")
    return 0


def cmd_bound(args: argparse.Namespace) -> int:
    from testbed.defense.config import PAPER_MODE
    from testbed.eval.run.folder import check_out_dir
    from testbed.eval.run.scenario import apply_settings, load_scenario
    from testbed.eval.search.bound_table import bound_markdown, bound_rows, bound_setting, write_bound

    if args.out is not None:
        check_out_dir(args.out, args.force)
    sc = load_scenario(args.scenario).with_overrides(defense=args.defense, detector=args.detector)
    if args.paper_mode:
        sc = sc.with_overrides(defense_params={**sc.defense_params, **PAPER_MODE})
    sc = apply_settings(sc, args.set)
    speeds = _floats(args.speeds, "--speeds") if args.speeds else [sc.speed]
    sigma = None
    if args.sigma:
        sigma = _floats(args.sigma, "--sigma")
        if len(sigma) != 2 or min(sigma) < 0:
            raise UserError(f"--sigma takes LATERAL,HEADING (m, rad, >= 0), got {args.sigma!r}")
    if args.k_sigma < 0:
        raise UserError(f"--k-sigma must be >= 0, got {args.k_sigma:g}")
    setting = bound_setting(sc, None if sigma is None else (sigma[0], sigma[1]))
    rows = bound_rows(setting, speeds, args.k_sigma, on_car=sc if args.on_car else None)
    title = (f"deviation bound: {sc.track}, {sc.vehicle}, defense {sc.defense}"
             f"{' (paper mode)' if args.paper_mode else ''}, control {sc.rates.control_hz:g} Hz, "
             f"camera {sc.rates.camera_hz:g} Hz, detector {sc.detector}, k = {args.k_sigma:g}")
    print(title)
    print(bound_markdown(rows))
    if args.out is not None:
        print(f"table: {write_bound(args.out, rows, title, args.force)}")
    return 0


def _floats(text: str, flag: str) -> list[float]:
    """A comma list of numbers, or a one-line UserError naming `flag`."""
    try:
        return [float(v) for v in text.split(",")]
    except ValueError:
        raise UserError(f"{flag} takes a comma list of numbers, got {text!r}") from None


def cmd_security_margin(args: argparse.Namespace) -> int:
    from testbed.eval.experiments.security_margin import plan_cells, security_margin

    def names(text: str | None, sep: str = ",") -> list[str] | None:
        return None if text is None else [n.strip() for n in text.split(sep)]

    try:
        seeds = None if args.seeds is None else [int(v) for v in args.seeds.split(",")]
    except ValueError:
        raise UserError(f"--seeds takes a comma list of integers, got {args.seeds!r}") from None
    threats = names(args.threats, ";")
    cells = plan_cells(roads=names(args.roads), defenses=names(args.defenses), threats=threats, seeds=seeds,
                       budget=args.budget)
    print(f"security margin: {len(cells)} searches of {args.budget} trials into {args.out}")
    table = security_margin(cells, args.out, announce=lambda line: print(line, flush=True), workers=args.workers,
                            backend=args.backend, address=args.address, timeout=args.timeout,
                            progress=sys.stderr.isatty())
    print(table.read_text())
    print(f"table: {table} and {table.with_suffix('.csv')}")
    return 0


def search_victim(args: argparse.Namespace):
    """The search's victim: the scenario with --defense/--detector/--localization, paper mode and --set."""
    from testbed.defense.config import PAPER_MODE
    from testbed.defense.registry import DEFENSES
    from testbed.eval.run.scenario import apply_settings, load_scenario

    sc = load_scenario(args.scenario)
    if sc.attack:
        raise UserError(f"scenario {args.scenario} already has an attack; the search chooses the attack: give a "
                        f"scenario without one")
    sc = sc.with_overrides(detector=args.detector, localization=args.localization, defense=args.defense)
    if args.paper_mode:
        if not set(PAPER_MODE) <= DEFENSES.get(sc.defense).reads:
            raise UserError(f"--paper-mode sets LD3's options, which defense {sc.defense!r} does not read: add "
                            f"--defense ld3")
        sc = sc.with_overrides(defense_params={**sc.defense_params, **PAPER_MODE})
    return apply_settings(sc, args.set)


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(prog="ld3", description=__doc__.splitlines()[0])
    parser.add_argument("--debug", action="store_true", help="let any error show its full traceback")
    sub = parser.add_subparsers(dest="cmd", required=True)

    p = sub.add_parser("run", help="run one scenario and write summary.json, trajectory.csv, birdseye.png")
    _add_run_overrides(p)
    p.add_argument("--video", action="store_true", help="also write camera.mp4 (H.264) with the lane-detection "
                                                        "overlay and the signals")
    p.add_argument("--record", action="store_true", help="also write run.mcap (Foxglove): camera, poses, map lines, "
                                                         "signals, attack")
    p.set_defaults(func=cmd_run)

    p = sub.add_parser("scenarios", help="list the shipped scenarios")
    p.set_defaults(func=cmd_scenarios)

    p = sub.add_parser("compare", help="a table and an overlay plot of the physical deviation of any finished runs")
    p.add_argument("runs", nargs="+", type=Path, help="run folders (each with summary.json and trajectory.csv)")
    p.add_argument("--out", type=Path, default=Path("runs/compare"), help="where report.md and deviations.png go")
    p.set_defaults(func=cmd_compare)

    p = sub.add_parser("figures", help="draw birdseye.png and ar_fusion.png of the runs under a folder whose runs "
                                       "left them for later (a search's trials), from their files")
    p.add_argument("dir", type=Path, help="a run folder, or a campaign or search folder holding run folders")
    p.set_defaults(func=cmd_figures)

    p = sub.add_parser("components", help="every registered defense, lane detector, localization, attack and "
                                          "campaign, with what it needs (markdown)")
    p.set_defaults(func=cmd_components)

    p = sub.add_parser("schema", help="the JSON Schema of the scenario TOML, from the registries (for editors and CI)")
    p.add_argument("--out", type=Path, help="write it here instead of stdout")
    p.set_defaults(func=cmd_schema)

    p = sub.add_parser("demo", help="run the default attacked scenario with and without LD3 and write a report")
    p.add_argument("--out", type=Path, default=Path("runs/demo"))
    p.set_defaults(func=cmd_demo)

    p = sub.add_parser("tracks", help="track presets")
    tsub = p.add_subparsers(dest="tracks_cmd", required=True)
    tsub.add_parser("list", help="list presets")
    routes = tsub.add_parser("routes", help="the drivable routes of an OpenDRIVE file, as track specs")
    routes.add_argument("file", help="xodr:PATH")
    show = tsub.add_parser("show", help="bird's-eye picture of a preset or an OpenDRIVE route")
    show.add_argument("name", help="NAME[@SEED] or xodr:PATH[#ROAD,ROAD,...][@LANE]")
    show.add_argument("--out", type=Path)
    export = tsub.add_parser("export", help="write a track as OpenDRIVE 1.7 (docs/opendrive.md)")
    export.add_argument("name", help="NAME[@SEED] or xodr:PATH[#ROAD,ROAD,...][@LANE]")
    export.add_argument("--format", choices=["xodr"], default="xodr")
    export.add_argument("--out", type=Path, help="default NAME-SEED.xodr")
    p.set_defaults(func=cmd_tracks)

    from testbed.defense.registry import DEFENSES
    from testbed.eval.campaign.driver import CAMPAIGN_BACKENDS
    from testbed.localization.registry import LOCALIZATIONS
    from testbed.perception.detectors.registry import DETECTORS

    backends = CAMPAIGN_BACKENDS.names()
    p = sub.add_parser("search", help="worst-case attack search: the attack a threat model allows that does most "
                                      "harm to a defense (Optuna over the adaptive attack families)")
    p.add_argument("scenario", help="the victim: a shipped scenario name or a .toml path (without an attack)")
    p.add_argument("--threat", required=True, metavar="CAPS",
                   help="threat model, a comma list of gnss, msf-output, ld-output, road-paint")
    p.add_argument("--budget", type=int, required=True, help="number of trials (closed-loop runs)")
    p.add_argument("--out", type=Path, required=True, help="search folder; rerunning it resumes the search")
    p.add_argument("--defense", choices=DEFENSES.names(), metavar="NAME", help="the victim's defense")
    p.add_argument("--detector", choices=DETECTORS.names(), metavar="NAME", help="the victim's lane detector")
    p.add_argument("--localization", choices=LOCALIZATIONS.names(), metavar="NAME", help="the victim's localization")
    p.add_argument("--paper-mode", action="store_true", help="LD3 as the paper writes it (PAPER_MODE)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override the victim's scenario as `ld3 run --set` does (repeatable)")
    p.add_argument("--seed", dest="search_seed", type=int, default=0,
                   help="sampler seed: the same seed gives the same trials (the victim's seed is --set seed=N)")
    p.add_argument("--objective", choices=("loss", "undetected", "overall"), default="loss",
                   help="loss (default): any lane departure or contact, detected or not, ranked by max |D|; "
                        "undetected: |D| before detection first, then |D| at all; overall: max |D| first")
    p.add_argument("--batch", type=int, default=8, help="trials asked of the sampler at once (default 8; part of "
                                                        "the search's identity, independent of --workers)")
    p.add_argument("--workers", type=int, help="parallel runs (as `ld3 campaign --workers`)")
    p.add_argument("--backend", choices=backends, default="local", help="local (default) or ray")
    p.add_argument("--address", help="ray: the cluster to connect to")
    p.add_argument("--timeout", type=seconds, metavar="SECONDS", help="time limit of each trial's run")
    p.set_defaults(func=cmd_search)

    p = sub.add_parser("bound", help="the largest lateral deviation an attacker reaches before LD3 alarms (a linear "
                                     "program on the closed-loop lateral model), per speed, beside the lane straddle")
    p.add_argument("scenario", help="shipped scenario name or .toml path: its vehicle, rates, [control], [defense]")
    p.add_argument("--defense", choices=DEFENSES.names(), metavar="NAME", default="ld3",
                   help="defense with LD3's detection: ld3 (default) or ld3-naive-ar")
    p.add_argument("--detector", choices=DETECTORS.names(), metavar="NAME",
                   help="lane detector whose measured benign residual σ widens b (default: the scenario's)")
    p.add_argument("--paper-mode", action="store_true", help="LD3 as the paper writes it (unbounded: no check "
                                                             "between detections, no heading check)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override the scenario as `ld3 run --set` does, e.g. defense.heading_tau=0.2 (repeatable)")
    p.add_argument("--speeds", metavar="LIST", help="comma list of speeds (m/s; default: the scenario's)")
    p.add_argument("--sigma", metavar="LAT,HEAD", help="benign residual std, lateral (m) and heading (rad) "
                                                      "(default: measured for the detector)")
    p.add_argument("--k-sigma", type=float, default=1.0, help="b_eff = b + k·σ (default 1)")
    p.add_argument("--on-car", action="store_true", help="also solve it on the closed loop's responses identified "
                                                         "on the car in simulation (three short runs a speed)")
    p.add_argument("--out", type=Path, help="write table.md, table.csv, bound.png here")
    p.add_argument("--force", action="store_true", help="replace a bound table already in --out")
    p.set_defaults(func=cmd_bound)

    p = sub.add_parser("security-margin", help="the security-margin table: a worst-case search (objective loss) per "
                                               "road × threat × defense × sampler seed, with LD3's bound; resumable")
    p.add_argument("--out", type=Path, default=Path("runs/security-margin"),
                   help="folder of the cells and table.md/table.csv (default runs/security-margin); rerun to resume")
    p.add_argument("--budget", type=int, default=120, help="trials per search (default 120)")
    p.add_argument("--seeds", metavar="LIST", help="sampler seeds, comma list (default 0,1,2)")
    p.add_argument("--roads", metavar="LIST", help="comma list of presets and held-out layouts (default: every "
                                                    "preset, highway@101, urban-curvy@101)")
    p.add_argument("--defenses", metavar="LIST", help="comma list of ld3, ld3-paper, naive-ar, savior (default all)")
    p.add_argument("--threats", metavar="LIST", help="semicolon list of threat models (default "
                                                     "gnss;msf-output;ld-output;msf-output,ld-output)")
    p.add_argument("--workers", type=int, help="parallel runs per search (as `ld3 campaign --workers`)")
    p.add_argument("--backend", choices=backends, default="local", help="local (default) or ray")
    p.add_argument("--address", help="ray: the cluster to connect to")
    p.add_argument("--timeout", type=seconds, metavar="SECONDS", help="time limit of each trial's run")
    p.set_defaults(func=cmd_security_margin)

    p = sub.add_parser("campaign", help="reproduce one of the paper's experiments (`ld3 campaign list`)")
    p.add_argument("name", help="campaign name, or `list`")
    p.add_argument("--out", type=Path, help="output directory (default runs/campaign-NAME); reruns resume, redoing "
                                             "unfinished runs (redone.txt)")
    p.add_argument("--detector", default="neural", help="lane detector for the runs that use one")
    p.add_argument("--workers", type=int, help="local: worker processes (default 2; 1: every run in this process); "
                                                "ray: CPUs of the local Ray instance (default 2), or with --address "
                                                "the most runs in flight (default: every CPU of the cluster)")
    p.add_argument("--backend", choices=backends, help="where the runs execute: local (default) or ray (needs "
                                                       "pip install '.[ray]')")
    p.add_argument("--address", help="ray: the cluster to connect to (e.g. auto, or ray://HEAD:10001); without it "
                                     "a local Ray instance is started")
    p.add_argument("--timeout", type=seconds, metavar="SECONDS",
                   help="time limit of each run (default 120 s + 10 × its simulated duration); a run over it is "
                        "stopped and listed in failures.txt")
    p.add_argument("--runs", metavar="GLOB", help="only the runs whose id matches GLOB (or one of comma-separated "
                                                  "GLOBs), e.g. 'local@101-*'")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override every run's scenario as `ld3 run --set` does, e.g. defense.heading=msf")
    p.add_argument("--attack", action="append", default=[], metavar="SPEC",
                   help="compose this attack after every run's own (repeatable; `ld3 run --attack` syntax)")
    p.add_argument("--budget", type=int, help="search campaigns (adaptive): trials of each search (default 24)")
    p.add_argument("--maps", nargs="+", default=[], metavar="DIR|FILE",
                   help="campaign maps: the OpenDRIVE files, or folders of them, whose default routes it drives")
    figures = p.add_mutually_exclusive_group()
    figures.add_argument("--figures-later", action="store_true",
                         help="runs write believed.csv in place of birdseye.png and ar_fusion.png, which `ld3 "
                              "figures OUT` draws later (campaigns whose runs write the standard outputs; the "
                              "default of those whose help says so)")
    figures.add_argument("--figures-now", action="store_true",
                         help="runs draw birdseye.png and ar_fusion.png at their end, also in a campaign that "
                              "leaves them for later by default (fusionripper-grid, ablation)")
    p.set_defaults(func=cmd_campaign)

    p = sub.add_parser("paper", help="every experiment of the paper (resumable) and one report with the paper's "
                                     "values beside ours")
    p.add_argument("--quick", action="store_true", help="a reduced set (fewer start times, seeds and layouts) that "
                                                        "still fills every table")
    p.add_argument("--out", type=Path, default=Path("paper"), help="output directory: one folder per campaign, "
                                                                    "report.md and figures (default ./paper)")
    p.add_argument("--workers", type=int, default=2, help="worker processes (1: every run in this process)")
    p.add_argument("--detector", default="neural", help="camera lane detector of the experiments that use one")
    p.add_argument("--timeout", type=seconds, metavar="SECONDS",
                   help="time limit of each run (default 120 s + 10 × its simulated duration)")
    p.add_argument("--backend", choices=backends, default="local", help="where the runs execute: local (default) or "
                                                                        "ray (needs pip install '.[ray]')")
    p.add_argument("--address", help="ray: the cluster to connect to (e.g. auto); without it a local Ray instance")
    p.set_defaults(func=cmd_paper)

    p = sub.add_parser("patch-figure", help="before/after camera frames of a dirty-road patch (drp-patch) with the "
                                            "detected lines and D_LD")
    p.add_argument("--attack", default=DEMO_PATCH, help=f"drp-patch spec (default: {DEMO_PATCH}, a patch over the "
                   "right line whose edge the neural detector follows)")
    p.add_argument("--track", default="urban-straight")
    p.add_argument("--detector", default="neural", choices=["neural", "classical"])
    p.add_argument("--ahead", type=float, default=8.0, help="camera distance before the patch (m)")
    p.add_argument("--out", type=Path, default=Path("runs/drp-patch/before-after.png"))
    p.set_defaults(func=cmd_patch_figure)

    p = sub.add_parser("bench", help="benchmarks (not tests): loop, render, ld (lane detectors), map, defense")
    p.add_argument("what", choices=["loop", "render", "ld", "map", "defense"])
    p.add_argument("--json", action="store_true", help="print the result as one JSON object")
    loop = p.add_argument_group("loop", "the closed loop: real-time factor, bare-physics real-time factor of the "
                                "same world and car, their ratio, and the split of time between the loop's parts")
    loop.add_argument("--camera", choices=["on", "off"], help="render the camera at its rate (default on), or run "
                      "without a camera (a detector that reads it is refused)")
    loop.add_argument("--scenario", help="scenario preset (default urban-straight)")
    loop.add_argument("--speed", type=float, help="target speed, m/s (default: the scenario's)")
    loop.add_argument("--localization", help="localization (default: the scenario's)")
    loop.add_argument("--seconds", type=float, help="simulated seconds (default 20)")
    loop.add_argument("--traffic", type=int, help="traffic cars on the road (sets traffic.vehicles; default: the "
                      "scenario's)")
    loop.add_argument("--detector", help="lane detector (default neural; with --camera on the camera is rendered "
                      "even for a detector that does not read it)")
    loop.add_argument("--ground", choices=["canvas", "mesh"],
                      help="how the camera draws the road surface: ground canvas (default) or TinyRenderer meshes")
    loop.add_argument("--set", dest="settings", action="append", metavar="KEY=VALUE",
                      help="override the scenario as `ld3 run --set` does (repeatable), e.g. rates.control_hz=40")
    p.set_defaults(func=cmd_bench)

    from testbed.eval.analysis.control_commands import add_control_parser
    from testbed.perception.commands import add_ld_parser

    add_ld_parser(sub)
    add_control_parser(sub)
    for plugin in entry_points(group=PLUGIN_GROUP):
        plugin.load()(sub)
    return parser


USER_ERRORS: tuple[type[BaseException], ...] = (UserError, FileNotFoundError, FileExistsError, PermissionError,
                                                IsADirectoryError, NotADirectoryError)
"""What the user can fix: printed as one line, exit 2. Anything else is a bug (internal error, exit 70)."""
EXIT_INTERNAL = 70


def _user_message(exc: BaseException) -> str:
    """One line for the user: a path error names the path and what is wrong with it."""
    if isinstance(exc, OSError) and exc.filename is not None:
        return one_line(f"cannot use {exc.filename}: {exc.strerror} (check --out and the paths given)")
    return one_line(str(exc))


_TERMINATED = threading.Event()
"""Set by SIGTERM: an interrupt that surfaces as another exception (raised inside a compiled module's initialisation,
which reports it as ImportError) is still reported as the interrupt."""


def _terminate_as_interrupt(signum: int, frame: object) -> None:
    """SIGTERM ends a command as Ctrl-C does: the output being written is removed, an earlier one kept."""
    _TERMINATED.set()
    raise KeyboardInterrupt


def main(argv: list[str] | None = None) -> int:
    if threading.current_thread() is not threading.main_thread():
        return _main(argv)
    _TERMINATED.clear()
    previous = signal.signal(signal.SIGTERM, _terminate_as_interrupt)
    try:
        return _main(argv)
    finally:
        signal.signal(signal.SIGTERM, previous)


def _main(argv: list[str] | None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    func: Callable[[argparse.Namespace], int] = args.func
    if args.debug:
        return func(args)
    try:
        return func(args)
    except USER_ERRORS as exc:
        print(f"ld3: error: {_user_message(exc)}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("ld3: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:
        if _TERMINATED.is_set():
            print(f"ld3: interrupted ({type(exc).__name__} while it ended)", file=sys.stderr)
            return 130
        print(f"ld3: internal error (a bug, not your input): {type(exc).__name__}: {one_line(str(exc))}; rerun "
              f"with --debug for the traceback", file=sys.stderr)
        return EXIT_INTERNAL


if __name__ == "__main__":
    sys.exit(main())
