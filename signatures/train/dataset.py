"""Training / evaluation datasets: scenes drawn from the paper's 3-D grid, simulated, featurised.

Why it is built this way:

* Geometry comes from the paper's grid (-1000 m .. 1000 m, 10 m spacing). The grid is
  cut into 100 m blocks and every block is assigned to *one* split (train / val /
  test) by a fixed hash of the block. Neighbouring grid points (near-identical
  returns) therefore never straddle splits, whatever the dataset seed.
* Each sample's simulator seed is derived from (dataset seed, split, index): two
  datasets with different seeds or splits never share a noise realisation.
* Generation is chunked (2 worker processes by default, or any `concurrent.futures`
  executor: `chunks_on` runs the chunks on a Dask cluster); only the feature vectors
  and RD patches are kept, never the IQ cubes.
* Scenes come from the one scene sampler (`signatures.sim.sampling`), with this module's
  distribution (`scene_distribution`) and the grid as the position.
* The waveform is data (`signatures.radar.Preset`): the spec carries it to the worker
  processes, and the cache key digests its parameters (a shipped preset by its name, as always).
* The result is cached as `.npz` (no pickle) under a key that digests everything the
  samples depend on, so a retrain does not re-simulate: the featurizer, the explicit feature
  and simulator versions and the code that computes the samples (`feature_version`).
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Executor, ProcessPoolExecutor
from contextlib import contextmanager, nullcontext
from contextvars import ContextVar
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np

from signatures.errors import SignaturesError
from signatures.profiles import NON_UAV_CLASSES, UavProfile
from signatures.radar import TRAINABLE_DOMAINS, Preset, get_preset
from signatures.sim.sampling import NuisanceDistribution, SceneDistribution, sample_scene
from signatures.sim.scene import Scene

#: Bump when the scene sampling (`scene_distribution`, `signatures.sim.sampling`) changes: cached datasets
#: are then regenerated.
GENERATOR_VERSION = 1
SPLITS = {"train": 0, "val": 1, "test": 2}
GRID_STEP_M = 10.0
GRID_HALF_M = 1000.0
BLOCK_M = 100.0
_SPLIT_SALT = b"uav-radar-authn/split/1"
#: Radial speeds of moving targets (m/s, either sign); below the paper preset's 22 m/s.
MOVING_SPEEDS_MPS = (2.0, 5.0, 10.0, 15.0, 20.0)
HOVER_FRACTION = 0.4
MIN_RANGE_M = 20.0

Featurizer = Callable[..., Any]


class DatasetError(SignaturesError):
    """A dataset that cannot be generated or read back."""


def block_split(x: float, y: float, z: float) -> str:
    """Split of the 100 m grid block holding (x, y, z): 70 % train, 10 % val, 20 % test."""
    b = tuple(int(math.floor((c + GRID_HALF_M) / BLOCK_M)) for c in (x, y, z))
    h = hashlib.blake2b(_SPLIT_SALT + repr(b).encode(), digest_size=8).digest()
    r = int.from_bytes(h, "little") % 10
    return "train" if r < 7 else ("val" if r < 8 else "test")


@dataclass(frozen=True)
class DatasetSpec:
    """Everything a dataset depends on (its cache key digests all of it).

    `preset`: the waveform, or the name of a shipped preset (resolved to it on construction).
    """

    preset: Preset | str
    profiles: tuple[UavProfile, ...]
    split: str
    n: int
    seed: int = 0
    snr_db: tuple[float, float] | float = (-5.0, 30.0)
    max_elevation_deg: float = 60.0
    clutter_fraction: float = 0.25
    clutter_db: tuple[float, float] = (0.0, 10.0)
    include_non_uav: bool = True
    feature_version: str = ""
    #: domain randomisation of every airframe and bird scene (None: the plain simulator)
    nuisance: NuisanceDistribution | None = None

    def __post_init__(self) -> None:
        if self.split not in SPLITS:
            raise DatasetError(f"unknown split {self.split!r} (known: {', '.join(SPLITS)})")
        if self.n < 1:
            raise DatasetError("a dataset needs at least one sample")
        if isinstance(self.preset, str):
            object.__setattr__(self, "preset", get_preset(self.preset))
        if self.waveform.domain not in TRAINABLE_DOMAINS:
            raise DatasetError(f"training for domain {self.waveform.domain} is not supported "
                               f"(trainable: {', '.join(TRAINABLE_DOMAINS)})")
        if self.waveform.domain == "cw" and self.waveform.n_samples != 1:
            raise DatasetError(f"a CW waveform records one sample per pulse, this one has {self.waveform.n_samples}")

    @property
    def waveform(self) -> Preset:
        assert isinstance(self.preset, Preset)  # resolved in __post_init__
        return self.preset

    @property
    def classes(self) -> tuple[str, ...]:
        """Labels in a fixed order: profiles (as given), then bird and none."""
        uav = tuple(p.slug for p in self.profiles)
        return uav + (NON_UAV_CLASSES if self.include_non_uav else ())

    def key(self) -> str:
        """Digest of every field; a shipped preset enters by its name (the keys of datasets
        cached before waveforms were data), any other waveform by its parameters."""
        doc: dict[str, Any] = {f.name: getattr(self, f.name) for f in fields(self)}
        if self.nuisance is None:  # the keys of datasets cached before randomisation existed
            del doc["nuisance"]
        else:
            doc["nuisance"] = asdict(self.nuisance)
        doc["profiles"] = [p.to_dict(json=True) for p in self.profiles]
        wf = self.waveform
        doc["preset"] = wf.name if wf.shipped else {"name": wf.name, "key": wf.key, "max_range_m": wf.max_range_m}
        doc["generator_version"] = GENERATOR_VERSION
        blob = json.dumps(doc, sort_keys=True, separators=(",", ":")).encode()
        return hashlib.sha256(blob).hexdigest()[:24]


@dataclass
class Dataset:
    """Feature matrix plus labels and the scene parameters of every sample."""

    X: np.ndarray  # (n, n_features) float32
    rd: np.ndarray  # (n, h, w) float32 RD patches
    y: np.ndarray  # (n,) str labels
    moving: np.ndarray  # (n,) bool operational state (radial speed != 0)
    snr_db: np.ndarray
    range_m: np.ndarray
    speed_mps: np.ndarray
    elevation_deg: np.ndarray
    feature_ms: np.ndarray  # feature-extraction wall time per sample
    classes: tuple[str, ...] = field(default=())
    feature_names: tuple[str, ...] = field(default=())

    def __len__(self) -> int:
        return int(self.y.shape[0])

    def save(self, path: Path) -> None:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".tmp.npz")
        np.savez_compressed(tmp, **{k: getattr(self, k) for k in _ARRAYS},
                            classes=np.array(self.classes, dtype=str),
                            feature_names=np.array(self.feature_names, dtype=str))
        os.replace(tmp, path)

    @classmethod
    def load(cls, path: Path) -> "Dataset":
        try:
            with np.load(path, allow_pickle=False) as z:
                arrays = {k: z[k] for k in _ARRAYS}
                return cls(**arrays, classes=tuple(str(c) for c in z["classes"]),
                           feature_names=tuple(str(c) for c in z["feature_names"]))
        except (OSError, KeyError, ValueError) as exc:
            raise DatasetError(f"{path}: unreadable dataset cache ({exc})") from None

    @staticmethod
    def concat(parts: Sequence["Dataset"]) -> "Dataset":
        arrays = {k: np.concatenate([getattr(p, k) for p in parts]) for k in _ARRAYS}
        return Dataset(**arrays, classes=parts[0].classes, feature_names=parts[0].feature_names)


_ARRAYS = ("X", "rd", "y", "moving", "snr_db", "range_m", "speed_mps", "elevation_deg", "feature_ms")


def _draw_point(rng: np.random.Generator, spec: DatasetSpec, max_range: float) -> tuple[float, float]:
    """(range_m, elevation_deg) of a grid point of the spec's split, inside the radar's range and
    elevation cover."""
    n = int(2 * GRID_HALF_M / GRID_STEP_M) + 1
    sin_max = math.sin(math.radians(spec.max_elevation_deg))
    for _ in range(10_000):
        x, y, z = (rng.integers(0, n, 3) * GRID_STEP_M - GRID_HALF_M).tolist()
        r = math.sqrt(x * x + y * y + z * z)
        if MIN_RANGE_M <= r <= max_range and abs(z) <= sin_max * r and block_split(x, y, z) == spec.split:
            return r, math.degrees(math.asin(z / r))
    raise DatasetError("no grid point satisfies the geometry constraints")  # pragma: no cover


def scene_distribution(spec: DatasetSpec) -> SceneDistribution:
    """The spec's scenes for `signatures.sim.sampling.sample_scene` (the position comes from the grid,
    see `draw_scene`). The order of draws is the one the shipped models were trained on."""
    return SceneDistribution(order=("position", "speed", "snr", "clutter"), hover_fraction=HOVER_FRACTION,
                             birds_hover=False, speeds_mps=MOVING_SPEEDS_MPS, snr_db=spec.snr_db,
                             clutter_band=(0.0, spec.clutter_fraction), clutter_db=spec.clutter_db,
                             bird_wing_m=(0.15, 0.6), bird_flap_hz=(2.0, 12.0), bird_flap_amplitude_deg=(20.0, 60.0),
                             nuisance=spec.nuisance)


def draw_scene(spec: DatasetSpec, index: int) -> tuple[Scene, int]:
    """Scene number `index` of the dataset and its simulator seed (pure function of both)."""
    rng = np.random.default_rng([spec.seed, SPLITS[spec.split], index, GENERATOR_VERSION])
    label = spec.classes[index % len(spec.classes)]
    target = label if label in NON_UAV_CLASSES else next(p for p in spec.profiles if p.slug == label)
    max_range = spec.waveform.max_range_m
    scene = sample_scene(rng, target, scene_distribution(spec), position=lambda g: _draw_point(g, spec, max_range))
    sim_seed = int(rng.integers(0, 2**63 - 1))
    return scene, sim_seed


def default_featurizer() -> Featurizer:
    """The package's feature extractor (`signatures.features.extract`)."""
    from signatures.features import extract

    return extract


#: Where a dataset's numbers come from besides the featurizer's module: the simulator, the scene
#: sampler and this module's scene distribution (`code_digest` follows their imports).
SAMPLE_CODE = ("signatures.sim.simulate", "signatures.sim.sampling", "signatures.train.dataset")


def feature_version(featurizer: Featurizer) -> str:
    """The featurizer's part of the cache key: its qualified name, the feature names, the feature
    and simulator versions (`signatures.features.FEATURE_VERSION`,
    `signatures.sim.simulate.SIMULATOR_VERSION`), the featurizer module's own `FEATURE_VERSION` if it
    has one, and a digest of the code the samples come from (`signatures.train.code_digest`: the
    featurizer's module, `SAMPLE_CODE` and our modules they import). The versions still say when
    the numbers change (tests/features/test_feature_version.py fails until they are bumped); the
    digest makes a cache written by other code (a reverted experiment) unreachable."""
    import importlib

    from signatures import features
    from signatures.sim import simulate
    from signatures.train.code_digest import code_digest

    mod = importlib.import_module(featurizer.__module__)
    names = getattr(mod, "FEATURE_NAMES", features.FEATURE_NAMES)
    doc = {"featurizer": f"{featurizer.__module__}.{featurizer.__qualname__}", "feature_names": list(names),
           "feature_version": features.FEATURE_VERSION, "simulator_version": simulate.SIMULATOR_VERSION,
           "module_feature_version": str(getattr(mod, "FEATURE_VERSION", "")),
           "code": code_digest((featurizer.__module__, *SAMPLE_CODE))}
    blob = json.dumps(doc, sort_keys=True).encode()
    return hashlib.sha256(blob).hexdigest()[:16]


def _chunk(spec: DatasetSpec, featurizer: Featurizer, start: int, stop: int) -> Dataset:
    """Simulate and featurise samples [start, stop) (runs in a worker process)."""
    from signatures.sim.domain import as_recorded
    from signatures.sim.simulate import simulate

    preset = spec.waveform
    feats, rds, meta = [], [], []
    for i in range(start, stop):
        scene, seed = draw_scene(spec, i)
        rec, _ = simulate(scene, preset, seed=seed)
        rec = as_recorded(rec, preset.domain)
        t0 = time.perf_counter()
        res = featurizer(rec)
        ms = (time.perf_counter() - t0) * 1e3
        feats.append(np.asarray(res.as_array(), dtype=np.float32))
        rds.append(np.asarray(res.rd_patch, dtype=np.float32))
        meta.append((scene.label, not scene.hovering and scene.kind != "none", scene.snr_db,
                     scene.range_m, scene.radial_speed_mps, scene.elevation_deg, ms))
    names = tuple(getattr(res, "names", None) or _names_of(featurizer))
    lab, mov, snr, rng_m, spd, el, ms = zip(*meta)
    return Dataset(X=np.stack(feats), rd=np.stack(rds), y=np.array(lab, dtype=str),
                   moving=np.array(mov, dtype=bool), snr_db=np.array(snr, dtype=np.float32),
                   range_m=np.array(rng_m, dtype=np.float32), speed_mps=np.array(spd, dtype=np.float32),
                   elevation_deg=np.array(el, dtype=np.float32), feature_ms=np.array(ms, dtype=np.float32),
                   classes=spec.classes, feature_names=names)


def _names_of(featurizer: Featurizer) -> tuple[str, ...]:
    import importlib

    return tuple(getattr(importlib.import_module(featurizer.__module__), "FEATURE_NAMES", ()))


def cache_dir() -> Path:
    """Feature cache: `$AUTHN_CACHE_DIR` or the user cache directory."""
    from core.settings import current

    env = current().cache_dir
    if env:
        return Path(env)
    import platformdirs

    return Path(platformdirs.user_cache_dir("uav-radar-authn")) / "datasets"


#: What the progress bars of `generate` add to their text (`progress_note`): '' for nothing.
_NOTE: ContextVar[str] = ContextVar("signatures_dataset_note", default="")


@contextmanager
def progress_note(text: str) -> Iterator[None]:
    """Inside the block, every `generate` progress bar says `text` too (e.g. the pace and the
    estimate of a long training run: why it takes what it takes)."""
    token = _NOTE.set(text)
    try:
        yield
    finally:
        _NOTE.reset(token)


#: The executor `generate` runs chunks on when none is given (None: its own process pool).
_EXECUTOR: ContextVar[Executor | None] = ContextVar("signatures_dataset_executor", default=None)


@contextmanager
def chunks_on(executor: Executor) -> Iterator[None]:
    """Inside the block, every `generate` call runs its chunks on `executor` (e.g. a Dask
    client's `get_executor()`), so callers such as `train_bundle` need no new argument."""
    token = _EXECUTOR.set(executor)
    try:
        yield
    finally:
        _EXECUTOR.reset(token)


def generate(spec: DatasetSpec, featurizer: Featurizer | None = None, *, workers: int = 2,
             chunk: int = 64, cache: Path | None | bool = None, progress: bool = False,
             executor: Executor | None = None) -> Dataset:
    """Simulate + featurise `spec.n` samples, or read them from the cache.

    `cache=None` uses `cache_dir()`, `False` disables caching, a Path picks the folder.
    `executor` (or the one `chunks_on` set) runs the chunks instead of a pool of `workers`.
    Results do not depend on `workers`, `chunk` or where a chunk ran (every sample has its own seed).
    """
    executor = _EXECUTOR.get() if executor is None else executor
    featurizer = featurizer or default_featurizer()
    if not spec.feature_version:
        spec = DatasetSpec(**{**spec.__dict__, "feature_version": feature_version(featurizer)})
    path = None
    if cache is not False:
        folder = cache_dir() if cache is None or cache is True else Path(cache)
        path = folder / f"{spec.waveform.name}-{spec.split}-{spec.n}-{spec.key()}.npz"
        if path.exists():
            return Dataset.load(path)
    bounds = [(s, min(s + chunk, spec.n)) for s in range(0, spec.n, chunk)]
    parts: list[Dataset] = []
    note = f": {_NOTE.get()}" if _NOTE.get() else ""
    text = f"simulating {spec.n} {spec.waveform.name} returns ({spec.split}){note}"
    with _progress(progress, text, spec.n) as advance:
        if executor is None and (workers <= 1 or len(bounds) == 1):
            for a, b in bounds:
                parts.append(_chunk(spec, featurizer, a, b))
                advance(b - a)
        else:
            with nullcontext(executor) if executor is not None else ProcessPoolExecutor(max_workers=workers) as pool:
                futures = [pool.submit(_chunk, spec, featurizer, a, b) for a, b in bounds]
                for fut, (a, b) in zip(futures, bounds):
                    parts.append(fut.result())
                    advance(b - a)
    data = Dataset.concat(parts)
    if path is not None:
        data.save(path)
    return data


class _progress:
    """A rich progress bar when asked for, a no-op otherwise."""

    def __init__(self, enabled: bool, text: str, total: int) -> None:
        self.enabled, self.text, self.total = enabled, text, total

    def __enter__(self) -> Callable[[int], None]:
        if not self.enabled:
            return lambda n: None
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TimeRemainingColumn

        self._p = Progress("[progress.description]{task.description}", BarColumn(), MofNCompleteColumn(),
                           TimeRemainingColumn(), transient=True)
        self._p.start()
        task = self._p.add_task(self.text, total=self.total)
        return lambda n: self._p.advance(task, n)

    def __exit__(self, *exc: object) -> None:
        if self.enabled:
            self._p.stop()
