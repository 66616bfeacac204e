"""Simulated returns of the airframes a site did not fly, in the site's own waveform: the other
side of every pair a site enrolment scores (docs/enrolment.md "One airframe").

A site that owns one type cannot fly the others past its radar, yet its card must say whether
radar tells its airframe from each of them. So the other registered and shipped profiles are
simulated in the waveform read from the site's recordings (the `models train --like` machinery:
the training distribution's scenes, `signatures.train.dataset.draw_scene`, of the test split, never
in the bundle's training set), and each return keeps what the 1:1 verification reads beside its
feature vector (the physics estimates), as a site recording does (`signatures.train.site_samples.SiteSample`).
Cached beside the training datasets, keyed like them.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from signatures.profiles import UavProfile
from signatures.radar import Preset

__all__ = ["N_OTHERS", "simulate_others"]

#: Simulated returns per other profile: with a site's 5 recordings claiming it, more than the 29
#: claims (`signatures.train.separability.MIN_SEPARABLE_CLAIMS`) a pair needs before it can be shown separable.
N_OTHERS = 40


def _spec(wf: Preset, profile: UavProfile, n: int, seed: int):  # -> DatasetSpec
    from signatures.train.dataset import DatasetSpec

    return DatasetSpec(preset=wf, profiles=(profile,), split="test", n=n, seed=seed, include_non_uav=False)


def _chunk(wf: Preset, profile: UavProfile, n: int, seed: int, start: int, stop: int) -> list[tuple]:
    """(features, physics) of returns [start, stop) of one profile (runs in a worker process)."""
    from dataclasses import asdict

    from signatures.train.dataset import draw_scene
    from signatures.sim.domain import as_recorded
    from signatures.features import extract
    from signatures.sim.simulate import simulate

    spec = _spec(wf, profile, n, seed)
    out = []
    for i in range(start, stop):
        scene, sim_seed = draw_scene(spec, i)
        rec, _ = simulate(scene, wf, seed=sim_seed)
        res = extract(as_recorded(rec, wf.domain))
        physics = {k: float(v) for k, v in res.physics.items()}
        physics.update({k: float(v) for k, v in asdict(res.features).items() if k not in physics})
        out.append((res.as_array().astype(np.float32), physics, bool(res.features.detected)))
    return out


def _key(wf: Preset, profile: UavProfile, n: int, seed: int) -> str:
    from signatures.train.dataset import default_featurizer, feature_version

    doc = {"spec": _spec(wf, profile, n, seed).key(), "features": feature_version(default_featurizer())}
    return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()[:16]


def _load(path: Path) -> list[tuple] | None:
    try:
        with np.load(path, allow_pickle=False) as z:
            X, P, names, det = z["X"], z["P"], [str(n) for n in z["names"]], z["detected"]
    except (OSError, KeyError, ValueError):
        return None
    return [(X[i], {k: float(P[i, j]) for j, k in enumerate(names) if math.isfinite(P[i, j])}, bool(det[i]))
            for i in range(len(X))]


def _save(path: Path, rows: list[tuple]) -> None:
    names = sorted({k for _, p, _ in rows for k in p})
    P = np.array([[p.get(k, np.nan) for k in names] for _, p, _ in rows], dtype=np.float64)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.npz")
    np.savez(tmp, X=np.stack([x for x, _, _ in rows]), P=P, names=np.array(names, dtype=str),
             detected=np.array([d for _, _, d in rows]))
    os.replace(tmp, path)


def simulate_others(wf: Preset, others: Sequence[UavProfile], n: int = N_OTHERS, seed: int = 0, workers: int = 2,
                    cache: Path | None | bool = None) -> dict[str, list[tuple[np.ndarray, dict[str, float], bool]]]:
    """Per profile of `others`, `n` simulated returns in waveform `wf` as (feature vector, physics
    estimates, detected). `cache`: None the training datasets' cache folder, False none, a Path."""
    from signatures.train.dataset import cache_dir

    folder = None if cache is False else (cache_dir() if cache is None or cache is True else Path(cache))
    out: dict[str, list[tuple]] = {}
    todo: list[UavProfile] = []
    for p in others:
        path = None if folder is None else folder / f"others-{wf.name}-{p.slug}-{n}-{_key(wf, p, n, seed)}.npz"
        rows = _load(path) if path is not None and path.exists() else None
        if rows is None:
            todo.append(p)
        else:
            out[p.slug] = rows
    if todo:
        step = max(1, math.ceil(n / max(1, workers)))
        jobs = [(p, a, min(a + step, n)) for p in todo for a in range(0, n, step)]
        if workers <= 1:
            parts = [_chunk(wf, p, n, seed, a, b) for p, a, b in jobs]
        else:
            with ProcessPoolExecutor(max_workers=workers) as pool:
                parts = list(pool.map(_chunk, *zip(*((wf, p, n, seed, a, b) for p, a, b in jobs))))
        for p in todo:
            rows = [r for (q, _, _), part in zip(jobs, parts) if q.slug == p.slug for r in part]
            out[p.slug] = rows
            if folder is not None:
                _save(folder / f"others-{wf.name}-{p.slug}-{n}-{_key(wf, p, n, seed)}.npz", rows)
    return {p.slug: out[p.slug] for p in others}
