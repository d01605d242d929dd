"""Labelled camera frames rendered from the testbed's own camera, for training and evaluating lane detectors.

An episode is one preset track at one seed (or one map's route, `xodr:FILE[#ROUTE]`) under one condition: the
camera is placed at a run of poses along a random lane (lateral offset up to ±1.5 m, yaw offset up to ±5°, camera
pitch and height jitter), the frame rendered and labelled from the map and from that frame itself
(`labels.ego_lines` with `labels.FrameVisibility`: a line whose paint the frame does not show standing out from
both sides of it is a missing line). On top of the preset's own look the episode randomises asphalt tone, marking
brightness, exposure, blur and noise, and erases the paint of random lane-line stretches (unmarked edges, gaps,
and the one-sided lines of lane splits and merges) so missing lines are common; the run of poses starts anywhere
along the track (bends, intersections). Each frame's meta keeps its lines' visible fractions and, on request,
their existence labels under other draws of the sensor randomisation of the same render (`label_draws`: how
repeatable a label is). With `traffic` > 0 each frame also shows up to that many traffic cars, drawn from a stream
of their own (so the frames without traffic stay the same): with probability `LEAD_PROBABILITY` a lead car in the
camera's lane `LEAD_GAP_RANGE_M` ahead of the car's front, the others in random lanes 5–60 m ahead; the labels
then come from the frame with the cars in it, and the meta keeps the share of the ego lines the cars hide
(`occluded`, `testbed.perception.training.occlusion`). Track seeds for training come from `TRAIN_SEEDS`;
`HELD_OUT_SEEDS` is reserved for evaluation, never trained on. Shards are `.npz` files: images (N, 160, 320, 3)
uint8 plus label arrays (each line's cubic and, at the network's anchors `anchor_x`, its own offset, NaN past where it
turns away); `meta` holds one JSON per frame.
"""

from __future__ import annotations

import json
import math
import zipfile
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from testbed.camera import FrontCamera
from testbed.conditions import CONDITIONS, get_condition
from testbed.errors import UserError
from testbed.perception.detectors.anchors import X_ANCHORS as ANCHOR_X
from testbed.perception.detectors.labels import FrameVisibility, PaintLayout, ego_lines
from testbed.perception.training import corner_roads
from testbed.perception.training.occlusion import occluded_fraction
from testbed.perception.training.seeds import HELD_OUT_SEEDS, TRAIN_SEEDS
from testbed.world import TileStreamer
from tracks.layout import Boundary, MarkingRun
from tracks.opendrive.load import PREFIX as XODR_PREFIX
from tracks.opendrive.model import OpenDriveError
from tracks.paint import AsphaltPainter, MarkingPainter, marking_coverage
from tracks.pose import Pose
from tracks.presets import PRESETS, load_track
from tracks.road import Track
from tracks.tile_frame import TileFrame
from vehicles.camera_rig import CameraRig
from vehicles.params import get_vehicle

MAX_LATERAL_OFFSET = 1.5  # m
MAX_YAW_OFFSET = math.radians(5.0)
PITCH_JITTER = math.radians(0.5)
HEIGHT_JITTER = 0.05  # m
POSES_PER_STATION = 2  # frames rendered at each station along the road (different pose and rig)
ERASED_PER_KM = 5.0  # unpainted stretches (15-80 m) per km of each lane line
LABEL_KEYS = ("left", "right", "left_exists", "right_exists", "lane_width", "deviation")
ANCHOR_KEYS = ("left_anchors", "right_anchors")  # each line's offset (m) at the network's anchors, NaN past the line
LEAD_PROBABILITY = 0.75
LEAD_GAP_RANGE_M = (3.0, 25.0)  # ego front to lead car rear
OTHERS_RANGE_M = (5.0, 60.0)  # centres of the other cars ahead of the camera's pose
TRAFFIC_LATERAL_M = 0.3  # a car's offset from its lane's centre, each side
PLACEMENT_DRAWS_PER_CAR = 50  # draws of a free place per car before the frame makes do with the cars placed
TRAFFIC_CAR = "sedan"
TRAFFIC_STREAM = 7  # tells the traffic's stream apart from the episode's and the label redraws'
TRAINING_ROADS = {corner_roads.NAME: corner_roads.corner_road}
"""Roads rendered only when asked for by name (`presets`), never by default: not presets of the campaigns."""
ROADS = {**PRESETS, **TRAINING_ROADS}


class MarkingFadePainter:
    """Scales the contrast of the lane-line paint against the asphalt by `brightness` (1 = unchanged)."""

    def __init__(self, brightness: float) -> None:
        self.brightness = brightness

    def paint(self, img: np.ndarray, frame: TileFrame, rng: np.random.Generator) -> None:
        cover = marking_coverage(frame)[..., None]
        if not cover.any():
            return
        base = np.median(img[::7, ::7].reshape(-1, 3), axis=0)
        work = img.astype(float)
        work = work + cover * (self.brightness - 1.0) * (work - base)
        img[:] = np.clip(work + 0.5, 0, 255).astype(np.uint8)


def erase_stretches(track, rng: np.random.Generator, per_km: float = ERASED_PER_KM) -> None:
    """Replace random stretches (15-80 m) of each lane line by 'none': unmarked edges and gaps."""
    new = []
    for boundary in track.boundaries:
        n = rng.poisson(per_km * track.length / 1000.0)
        gaps = sorted((float(a), float(a + rng.uniform(15.0, 80.0))) for a in rng.uniform(0, track.length, n))
        runs: list[MarkingRun] = []
        for run in boundary.runs:
            pieces = [(run.s0, run.s1)]
            for a, b in gaps:
                pieces = [p for lo, hi in pieces for p in ((lo, min(hi, a)), (max(lo, b), hi)) if p[1] > p[0]]
            covered = run.s0
            for lo, hi in pieces:
                if lo > covered:
                    runs.append(MarkingRun(covered, lo, "none"))
                runs.append(MarkingRun(lo, hi, run.kind))
                covered = hi
            if covered < run.s1:
                runs.append(MarkingRun(covered, run.s1, "none"))
        new.append(Boundary(boundary.t, tuple(runs)))
    track.boundaries = new


def sensor_randomise(img: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Extra exposure gain, blur and noise on a rendered frame."""
    out = img.astype(np.float32) * float(np.exp(rng.uniform(-0.35, 0.35)))
    if rng.random() < 0.3:
        out = cv2.GaussianBlur(out, (0, 0), float(rng.uniform(0.3, 1.0)))
    out += rng.normal(0.0, rng.uniform(0.0, 4.0), out.shape).astype(np.float32)
    return np.clip(out, 0, 255).astype(np.uint8)


@dataclass(frozen=True)
class Episode:
    """One track, seed and condition; frames are drawn from `seed` too. `track`, when given, is a map's track
    spec (`xodr:FILE[#ROUTE]`) rendered instead of the preset `preset` at `seed`, which then only names it."""

    preset: str
    seed: int
    condition: str
    track: str | None = None

    @property
    def track_spec(self) -> str:
        return self.track if self.track is not None else f"{self.preset}@{self.seed}"

    def build_track(self) -> Track:
        """The episode's road: the map route, the training-only road of that name (`TRAINING_ROADS`) or the
        preset."""
        if self.track is None and self.preset in TRAINING_ROADS:
            return TRAINING_ROADS[self.preset](self.seed)
        return load_track(self.track_spec)


def episodes(split: str, count: int, seed: int, conditions: Sequence[str] | None = None,
             presets: Sequence[str] | None = None, tracks: Sequence[str] | None = None) -> list[Episode]:
    """`count` episodes cycling over `presets` (or over the map `tracks`, `xodr:FILE[#ROUTE]`, instead) and over
    `conditions` (default: all of each), each track × condition pair once in every tracks × conditions
    episodes; track seeds drawn from the split (a map's seed only seeds its frames' draws)."""
    seeds = TRAIN_SEEDS if split == "train" else HELD_OUT_SEEDS
    if split not in ("train", "heldout"):
        raise ValueError(f"split must be 'train' or 'heldout', got {split!r}")
    conditions = _distinct("conditions", conditions, CONDITIONS)
    if tracks is not None and presets is not None:
        raise UserError("give either presets or map tracks, not both")
    if tracks is not None:
        specs: list[str | None] = list(_map_tracks(tracks))
        names = [map_track_name(t) for t in tracks]
    else:
        names = list(PRESETS) if presets is None else _distinct("presets", presets, ROADS)
        specs = [None] * len(names)
    rng = np.random.default_rng([seed, 0 if split == "train" else 1])
    out = []
    for i in range(count):
        k = i % len(names)
        condition = conditions[(i // len(names) + k) % len(conditions)]  # every pair per round
        out.append(Episode(names[k], int(rng.choice(seeds)), condition, specs[k]))
    return out


def map_track_name(spec: str) -> str:
    """The name a map's track spec goes by in a dataset's meta: the file's stem, with its route if given."""
    path, _, route = spec.removeprefix(XODR_PREFIX).partition("#")
    return Path(path).stem + (f"#{route}" if route else "")


def _map_tracks(tracks: Sequence[str]) -> list[str]:
    """`tracks` as a list, refused unless they are distinct `xodr:` specs of maps that load."""
    chosen = list(tracks)
    if not chosen or len(set(chosen)) != len(chosen) or any(not t.startswith(XODR_PREFIX) for t in chosen):
        raise UserError(f"tracks must be distinct map routes xodr:FILE[#ROUTE] (presets go to --presets); "
                        f"got {chosen}")
    for t in chosen:
        try:
            load_track(t)  # a map that does not load is refused here, in one line, not in a worker
        except OpenDriveError as exc:
            raise UserError(str(exc)) from None
    return chosen


def _distinct(what: str, chosen: Sequence[str] | None, names) -> list[str]:
    """`chosen` (default: every name) as a list, refused unless its entries are distinct members of `names`."""
    chosen = list(names) if chosen is None else list(chosen)
    if not chosen or any(c not in names for c in chosen) or len(set(chosen)) != len(chosen):
        raise UserError(f"{what} must be distinct names among {', '.join(names)}; got {chosen}")
    return chosen


def traffic_poses(track, lane, s: float, count: int, rng: np.random.Generator, ego_length: float) -> list[Pose]:
    """Up to `count` traffic car poses for a camera at arc length `s` of `lane` (see the module): the lead car
    first where drawn, no two cars of a lane overlapping, none past the road's end. Places are drawn at most
    `PLACEMENT_DRAWS_PER_CAR` × `count` times, so a road too short or narrow for `count` cars gets fewer."""
    car = get_vehicle(TRAFFIC_CAR)
    taken: list[tuple[int, float]] = []
    if count and rng.random() < LEAD_PROBABILITY:
        gap = float(rng.uniform(*LEAD_GAP_RANGE_M))
        taken.append((lane.index, s + 0.5 * ego_length + gap + 0.5 * car.length))
    for _ in range(PLACEMENT_DRAWS_PER_CAR * count):
        if len(taken) >= count:
            break
        index, at = int(rng.integers(len(track.lanes))), s + float(rng.uniform(*OTHERS_RANGE_M))
        if all(i != index or abs(at - a) > car.length + 1.0 for i, a in taken):
            taken.append((index, at))
    poses = []
    for index, at in taken:
        ln = track.lanes[index]
        if at < ln.length - 0.5 * car.length:
            x, y = ln.position(at, float(rng.uniform(-TRAFFIC_LATERAL_M, TRAFFIC_LATERAL_M)))
            poses.append(Pose(x, y, ln.heading_at(at)))
    return poses


def render_episode(ep: Episode, n_frames: int, vehicle: str = "sedan",
                   label_draws: int = 0, traffic: int = 0) -> Iterator[tuple[np.ndarray, dict]]:
    """Yield (image, label) for `n_frames` poses along one random lane of the episode's track; with
    `label_draws` > 0 each label's meta also holds `redrawn_exists`, the (left, right) existence labels of that
    many other sensor draws of the same render, drawn from their own stream (images and labels unchanged); with
    `traffic` > 0 up to that many traffic cars in each frame (see the module)."""
    key = [ep.seed, sum(map(ord, ep.preset)), sum(map(ord, ep.condition))]
    rng = np.random.default_rng(key)
    traffic_rng = np.random.default_rng([*key, traffic, TRAFFIC_STREAM])
    track = ep.build_track()
    condition = get_condition(ep.condition)
    erase_stretches(track, rng)
    track.painters = [
        AsphaltPainter(tone=float(rng.uniform(0.65, 1.35)), grain=float(rng.uniform(4.0, 10.0))),
        MarkingPainter(),
        MarkingFadePainter(float(rng.uniform(0.55, 1.1))),
        *condition.track_painters(ep.seed),
    ]
    ego = get_vehicle(vehicle)
    base_rig, ego_length = CameraRig(ego.camera), ego.length
    streamer = TileStreamer(track, condition.lighting, ahead_m=70.0, behind_m=5.0)
    layout = PaintLayout(track)
    car = get_vehicle(TRAFFIC_CAR)
    if traffic:
        streamer.add_traffic(traffic, car.length, car.width, car.height)
    try:
        along = [ln for ln in track.lanes if not ln.oncoming]  # the camera's car drives along the road
        lane = along[int(rng.integers(len(along)))]
        mean_step = max(1.0, min(6.0, POSES_PER_STATION * (track.length - 10.0) / n_frames))
        run = mean_step * n_frames / POSES_PER_STATION
        s = float(rng.uniform(0.0, max(1.0, track.length - run - 2.0)))
        for i in range(n_frames):
            if s > track.length - 2.0:
                break
            redraw_rng = np.random.default_rng([*key, i])
            cars = traffic_poses(track, lane, s, traffic, traffic_rng, ego_length) if traffic else []
            if traffic:
                streamer.place_traffic(dict(enumerate(cars)))
            image, label = _render_pose(track, lane, s, streamer, layout, base_rig, condition, rng, ep, label_draws,
                                        redraw_rng)
            if traffic:
                pose = Pose(*label["meta"]["pose"])
                hidden = occluded_fraction(track, pose, base_rig, cars, (car.length, car.width, car.height))
                label["meta"]["traffic"] = len(cars)
                label["meta"]["occluded"] = None if hidden is None else round(hidden, 4)
            yield image, label
            if i % POSES_PER_STATION == POSES_PER_STATION - 1:
                s += float(rng.uniform(0.4, 1.6)) * mean_step
    finally:
        streamer.close()


def _render_pose(track, lane, s: float, streamer: TileStreamer, layout: PaintLayout, base_rig: CameraRig,
                 condition, rng: np.random.Generator, ep: Episode, label_draws: int,
                 redraw_rng: np.random.Generator) -> tuple[np.ndarray, dict]:
    x, y = lane.position(s, float(rng.uniform(-MAX_LATERAL_OFFSET, MAX_LATERAL_OFFSET)))
    pose = Pose(x, y, lane.heading_at(s) + float(rng.uniform(-MAX_YAW_OFFSET, MAX_YAW_OFFSET)))
    pitch, height = float(rng.uniform(-PITCH_JITTER, PITCH_JITTER)), float(rng.uniform(-HEIGHT_JITTER, HEIGHT_JITTER))
    rig = base_rig.with_jitter(pitch, height)
    streamer.update(pose)
    clean = FrontCamera(streamer, rig, condition, rng).render(pose)
    image = sensor_randomise(clean, rng)
    truth = ego_lines(track, pose, FrameVisibility(image, rig, layout))
    redrawn = [ego_lines(track, pose, FrameVisibility(sensor_randomise(clean, redraw_rng), rig, layout))
               for _ in range(label_draws)]
    label = {
        "left": truth.left.coeffs, "right": truth.right.coeffs,
        "left_anchors": truth.left.offsets_at(ANCHOR_X), "right_anchors": truth.right.offsets_at(ANCHOR_X),
        "left_exists": truth.left.exists, "right_exists": truth.right.exists,
        "lane_width": truth.width, "deviation": truth.deviation,
        "meta": {"preset": ep.preset, "seed": ep.seed, "condition": ep.condition, "s": round(s, 2),
                 **({"track": ep.track} if ep.track is not None else {}),
                 "lane": truth.lane, "pose": [round(v, 4) for v in pose],
                 "left_kind": truth.left.kind, "right_kind": truth.right.kind,
                 "pitch_jitter_deg": round(math.degrees(pitch), 4), "height_jitter_m": round(height, 4),
                 "visible": [None if v is None else round(v, 4) for v in (truth.left.visible, truth.right.visible)]},
    }
    if redrawn:
        label["meta"]["redrawn_exists"] = [[t.left.exists, t.right.exists] for t in redrawn]
    return image, label


def write_shard(path: Path, images: list[np.ndarray], labels: list[dict]) -> None:
    """One shard: the images, the label arrays, the anchors' labels with their distances (`anchor_x`) where every
    label has them, and the metadata."""
    keys = LABEL_KEYS + (ANCHOR_KEYS if all(k in lb for lb in labels for k in ANCHOR_KEYS) else ())
    arrays = {k: np.asarray([lb[k] for lb in labels]) for k in keys}
    if ANCHOR_KEYS[0] in arrays:
        arrays["anchor_x"] = np.asarray(ANCHOR_X)
    meta = np.asarray([json.dumps(lb["meta"]) for lb in labels])
    np.savez(path, images=np.stack(images), meta=meta, **arrays)


@dataclass
class FrameSet:
    """Frames and labels loaded from a dataset directory (all shards concatenated); the anchors' labels are None
    for datasets written before they were (their lines are then labelled by the cubic alone)."""

    images: np.ndarray
    left: np.ndarray
    right: np.ndarray
    left_exists: np.ndarray
    right_exists: np.ndarray
    lane_width: np.ndarray
    deviation: np.ndarray
    meta: list[dict]
    left_anchors: np.ndarray | None = None
    right_anchors: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.images)


def iter_shards(directory: Path, limit: int | None = None) -> Iterator[FrameSet]:
    """The dataset in `directory` one shard at a time (at most `limit` frames in all): memory stays that of one
    shard for callers that convert as they go."""
    shards = sorted(Path(directory).glob("shard_*.npz"))
    if not shards:
        raise FileNotFoundError(f"no dataset shards (shard_*.npz) in {directory}")
    left = limit
    for shard in shards:
        if left is not None and left <= 0:
            return
        cat, meta = read_shard(shard, left)
        if left is not None:
            left -= len(meta)
        yield FrameSet(meta=meta, **cat)


SHARD_SHAPES = {"images": (4, 3), "left": (2, 4), "right": (2, 4), "left_exists": (1, None), "right_exists": (1, None),
                "lane_width": (1, None), "deviation": (1, None), "meta": (1, None)}
"""Each shard array's dimensions and last size (None: any); all hold one row per frame, numbers (images uint8)."""
ANCHOR_SHAPE = (2, len(ANCHOR_X))
"""The same of each `ANCHOR_KEYS` array, where a shard has them."""


def read_shard(shard: Path, limit: int | None = None) -> tuple[dict[str, np.ndarray], list[dict]]:
    """The label arrays (and images) and the per-frame metadata of one shard, at most `limit` frames; a shard that
    is not one `write_shard` wrote (not a zip of arrays, a missing key, an object array, rows that differ, a
    number that is not finite) is a UserError naming it."""
    try:
        with np.load(shard, allow_pickle=False) as z:
            missing = [k for k in SHARD_SHAPES if k not in z.files]
            if missing:
                raise UserError(f"{shard}: not a dataset shard: no {', '.join(missing)} (write one with `ld3 ld "
                                f"dataset`)")
            arrays = {k: z[k][:limit] for k in SHARD_SHAPES}
            meta = [json.loads(m) for m in arrays.pop("meta")]
            arrays.update(_anchor_labels(shard, z, limit))
    except UserError:
        raise
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile) as exc:  # truncated, pickled, bad JSON
        problem = " ".join(str(exc).split())[:200]
        raise UserError(f"{shard}: cannot read the dataset shard: {problem}") from None
    rows = {len(a) for a in arrays.values()} | {len(meta)}
    for key, array in arrays.items():
        ndim, last = SHARD_SHAPES.get(key, ANCHOR_SHAPE)
        if (array.ndim != ndim or (last is not None and array.shape[-1] != last) or array.dtype.kind not in "biuf"
                or (key == "images" and array.dtype != np.uint8)):
            raise UserError(f"{shard}: array {key!r} is {array.dtype} of shape {array.shape}, not a dataset's")
    if len(rows) != 1 or not all(isinstance(m, dict) for m in meta):
        raise UserError(f"{shard}: the arrays hold different numbers of frames")
    return arrays, meta


def _anchor_labels(shard: Path, z, limit: int | None) -> dict[str, np.ndarray]:
    """The shard's anchor labels (none in a shard written before them); refused where they were taken at other
    distances than the network's anchors."""
    present = [k for k in (*ANCHOR_KEYS, "anchor_x") if k in z.files]
    if not present:
        return {}
    if len(present) < len(ANCHOR_KEYS) + 1:
        raise UserError(f"{shard}: not a dataset shard: anchor labels without all of {', '.join(ANCHOR_KEYS)}, "
                        f"anchor_x")
    at = z["anchor_x"]
    if at.shape != (len(ANCHOR_X),) or not np.array_equal(at, ANCHOR_X):
        raise UserError(f"{shard}: its lines are labelled at {at.tolist()} m, the network's anchors are at "
                        f"{list(ANCHOR_X)} m: render the dataset again")
    return {k: z[k][:limit] for k in ANCHOR_KEYS}


def load_frames(directory: Path, limit: int | None = None) -> FrameSet:
    """All shards of the dataset in `directory` (at most `limit` frames) concatenated; the anchor labels only
    where every shard has them."""
    parts = list(iter_shards(directory, limit))
    keys = ("images", *LABEL_KEYS) + (ANCHOR_KEYS if all(p.left_anchors is not None for p in parts) else ())
    cat = {k: np.concatenate([getattr(p, k) for p in parts]) for k in keys}
    return FrameSet(meta=[m for p in parts for m in p.meta], **cat)


def _render_to_shard(job: tuple[Episode, int, Path, int, int]) -> int:
    ep, n_frames, path, label_draws, traffic = job
    frames = list(render_episode(ep, n_frames, label_draws=label_draws, traffic=traffic))
    if frames:
        write_shard(path, [f[0] for f in frames], [f[1] for f in frames])
    return len(frames)


def build_dataset(out: Path, frames: int, split: str = "train", seed: int = 0, frames_per_episode: int = 30,
                  workers: int = 1, progress: bool = False, conditions: Sequence[str] | None = None,
                  label_draws: int = 0, traffic: int = 0, presets: Sequence[str] | None = None,
                  tracks: Sequence[str] | None = None) -> int:
    """Render about `frames` labelled frames into `out` (one shard per episode; episodes of `presets`, or of the
    map routes `tracks`, in `conditions`, default all of each; each label also under `label_draws` other sensor
    draws, each frame with up to `traffic` cars, see `render_episode`); returns the frame count."""
    if label_draws < 0:
        raise ValueError(f"label_draws must be >= 0, got {label_draws}")
    if traffic < 0:
        raise ValueError(f"--traffic must be a number of cars >= 0, got {traffic}")
    from multiprocessing import get_context

    from tqdm import tqdm

    out = Path(out)
    n_eps = max(1, math.ceil(frames / frames_per_episode))
    jobs = [(ep, min(frames_per_episode, frames - i * frames_per_episode), out / f"shard_{i:05d}.npz", label_draws,
             traffic)
            for i, ep in enumerate(episodes(split, n_eps, seed, conditions, presets, tracks))]
    out.mkdir(parents=True, exist_ok=True)
    bar = tqdm(total=frames, desc=f"rendering {split}", unit="frame", disable=not progress)
    done = 0
    if workers > 1:
        with get_context("spawn").Pool(workers) as pool:
            for n in pool.imap_unordered(_render_to_shard, jobs):
                done += n
                bar.update(n)
    else:
        for job in jobs:
            n = _render_to_shard(job)
            done += n
            bar.update(n)
    bar.close()
    (out / "dataset.json").write_text(json.dumps({"split": split, "seed": seed, "frames": done,
                                                  "episodes": n_eps, "conditions": conditions or list(CONDITIONS),
                                                  "presets": [] if tracks else presets or list(PRESETS),
                                                  "tracks": list(tracks or []),
                                                  "held_out_seeds": [HELD_OUT_SEEDS.start, HELD_OUT_SEEDS.stop],
                                                  "label_draws": label_draws, "traffic": traffic}))
    return done
