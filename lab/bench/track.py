"""Tracks of consecutive dwells on the simulator: how correlated one airframe's dwells are, and
how many dwells the sequential test needs per decision (`authn bench --track`, docs/tracks.md).

A track is one `Scene` (airframe, its flown rotor rate and nuisances, geometry, SNR) rendered
dwell after dwell with a new simulator seed each (blade phases, yaw, noise, clutter draws) and
the range moving with the radial speed; its Remote ID follows the truth. Two scenes differ in
everything a scene draws. So the correlation of the verification LLRs of dwells of one scene,
against dwells of different scenes, is the part of the evidence that repeats with the airframe
and its geometry and that more dwells cannot average out (`authn.track`'s discount).
"""

from __future__ import annotations

import math
import statistics
import tempfile
from collections.abc import Callable
from dataclasses import dataclass, replace
from datetime import datetime, timedelta, timezone
from pathlib import Path
from typing import Any

import numpy as np

from authn.scenario import Broadcast, simulate_flight
from lab.bench.decisions import CLAIM_SCENES, bench_serial, is_right, register_identities
from signatures.profiles import shipped_profiles
from signatures.radar import get_preset
from signatures.recording import Recording
from signatures.sim.sampling import sample_scene
from signatures.sim.scene import Scene

#: Seconds between the starts of consecutive dwells of a track (a scanning radar's revisit).
DWELL_SPACING_S = 1.0
TRACK_CATEGORIES = ("genuine", "type_spoof")
DEFAULT_TRACK_SNRS = (0.0, 5.0, 10.0, 20.0)


def track_recordings(scene: Scene, preset: str, seeds: list[int], serial: str | None, azimuth_deg: float = 60.0,
                     start: datetime | None = None, spacing_s: float = DWELL_SPACING_S,
                     world: str = "training", broadcast: Broadcast | None = None) -> list[Recording]:
    """The dwells of one target: `scene` rendered once per seed, `spacing_s` apart, its range
    moving with its radial speed, each carrying the Remote ID of `serial` (None: none), or
    `broadcast` where given (a signed one, say). `world`: the training simulator, or `heldout`
    (lab.heldout, the signal model nothing was fitted to)."""
    pre = get_preset(preset)
    start = start or datetime.now(timezone.utc)
    out = []
    for i, seed in enumerate(seeds):
        sc = scene.model_copy(update={"range_m": max(1.0, scene.range_m + scene.radial_speed_mps * i * spacing_s)})
        when = start + timedelta(seconds=i * spacing_s)
        bc = broadcast or (Broadcast(serial=serial) if serial else None)
        if world != "training" and bc is not None:
            from lab.bench.worlds import render_claim

            out.append(render_claim(world, sc, pre, seed, bc, azimuth_deg, when))
            continue
        if world != "training":
            raise ValueError("a held-out track needs a serial to broadcast")
        out.append(simulate_flight(sc, pre, seed, bc, azimuth_deg=azimuth_deg, start_time=when)[0])
    return out


def _pair(cat: str, i: int, slugs: list[str]) -> tuple[str, str]:
    """(airframe flown, model claimed): a genuine claim, or a type spoof between shipped profiles."""
    flies = slugs[i % len(slugs)]
    return (flies, flies) if cat == "genuine" else (flies, slugs[(i + 1 + (i // 3) % 2) % len(slugs)])


def _scene(rng: np.random.Generator, slug: str, snr_db: float) -> Scene:
    return sample_scene(rng, shipped_profiles()[slug], replace(CLAIM_SCENES, snr_db=float(snr_db)))


def icc(groups: list[list[float]]) -> float:
    """Intra-class correlation of a one-way layout (groups = tracks, values = dwell LLRs): the share
    of the variance between tracks, (MSB - MSW) / (MSB + (k - 1) MSW) with k the mean group size
    (groups of fewer than 2 values are left out). 0 when there is no spread at all."""
    gs = [np.asarray(g, dtype=np.float64) for g in groups if len(g) >= 2]
    if len(gs) < 2:
        raise ValueError("need two groups of two values at least")
    n = sum(g.size for g in gs)
    grand = np.concatenate(gs).mean()
    ssb = sum(g.size * (g.mean() - grand) ** 2 for g in gs)
    ssw = sum(((g - g.mean()) ** 2).sum() for g in gs)
    msb, msw = ssb / (len(gs) - 1), ssw / (n - len(gs))
    k = n / len(gs)
    den = msb + (k - 1) * msw
    return 0.0 if den <= 0 else float((msb - msw) / den)


def _pearson(pairs: list[tuple[float, float]]) -> float:
    a = np.asarray(pairs, dtype=np.float64)
    if len(a) < 3 or a[:, 0].std() == 0 or a[:, 1].std() == 0:
        return float("nan")
    return float(np.corrcoef(a[:, 0], a[:, 1])[0, 1])


@dataclass(frozen=True)
class Dependence:
    """The correlation of dwell LLRs within and between tracks, per claim category."""

    preset: str
    world: str
    snr_db: float
    category: str
    tracks: int
    dwells: int
    icc: float  # intra-class correlation of the (capped) dwell LLRs, within one (flown, claimed) pair
    icc_pooled: float  # the same over the category's pairs pooled (their different means count as bias too)
    within: float  # Pearson, consecutive dwells of one track
    between: float  # Pearson, dwell j of track i against dwell j of track i + 1
    mean_llr: float
    sd_llr: float

    def to_json(self) -> dict[str, Any]:
        """The row as JSON (NaN, where too few scenes or dwells gave a number, as null)."""
        return {k: ((None if math.isnan(v) else round(v, 4)) if isinstance(v, float) else v)
                for k, v in self.__dict__.items()}


def _checker(tmp: str) -> Any:
    from authn.check import Checker

    db = f"sqlite:///{Path(tmp) / 'track.sqlite3'}"
    register_identities(db)
    return Checker(db)


def dwell_llrs(checker: Any, recs: list[Recording], serial: str, cap: float) -> list[float]:
    """Each dwell's verification LLR (capped at +-cap; dwells that verified nothing left out)."""
    from authn.check import CheckInput

    out = []
    for rec in recs:
        o = checker.decide_one(CheckInput.recording(rec, serial))
        v = o.radar.verification if o.radar is not None else None
        if v is not None and v.terms:
            out.append(max(-cap, min(cap, v.llr)))
    return out


def dependence(preset: str = "paper", n_tracks: int = 30, dwells: int = 6, snr_db: float = 10.0, seed: int = 7,
               progress: Callable[[int], None] | None = None, world: str = "training") -> list[Dependence]:
    """Per category: `n_tracks` random scenes (`CLAIM_SCENES` at `snr_db`), `dwells` dwells each.
    `icc` is the correlation the track's discount needs: dwells of one scene against dwells of
    other scenes of the same airframe making the same claim (a pair's mean is the claim's signal,
    its scene-to-scene spread the bias that repeats), weighted over the pairs."""
    from authn.track import DWELL_CAP_NATS

    slugs = list(shipped_profiles())
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        checker = _checker(tmp)
        for c_idx, cat in enumerate(TRACK_CATEGORIES):
            rng = np.random.default_rng([seed, c_idx, 31])
            groups: list[list[float]] = []
            pairs: dict[tuple[str, str], list[list[float]]] = {}
            for i in range(n_tracks):
                flies, claims = _pair(cat, i, slugs)
                scene = _scene(rng, flies, snr_db)
                az, base = float(rng.uniform(0.0, 360.0)), int(rng.integers(2**31 - dwells))
                recs = track_recordings(scene, preset, list(range(base, base + dwells)), bench_serial(claims), az,
                                        world=world)
                groups.append(dwell_llrs(checker, recs, bench_serial(claims), DWELL_CAP_NATS))
                pairs.setdefault((flies, claims), []).append(groups[-1])
                if progress:
                    progress(dwells)
            within = [(g[j], g[j + 1]) for g in groups for j in range(len(g) - 1)]
            between = [(a[j], b[j]) for a, b in zip(groups, groups[1:]) for j in range(min(len(a), len(b)))]
            flat = [x for g in groups for x in g]
            per_pair = [(sum(len(g) for g in gs), icc(gs)) for gs in pairs.values()
                        if sum(len(g) >= 2 for g in gs) >= 2]
            pooled_pairs = (sum(w * v for w, v in per_pair) / sum(w for w, _ in per_pair) if per_pair
                            else float("nan"))  # fewer than two scenes of any one pair
            rows.append(Dependence(preset, world, snr_db, cat, n_tracks, len(flat), pooled_pairs, icc(groups),
                                   _pearson(within), _pearson(between),
                                   statistics.fmean(flat) if flat else float("nan"),
                                   statistics.pstdev(flat) if flat else float("nan")))
    return rows


@dataclass(frozen=True)
class TrackTrial:
    """One track decided by the sequential test."""

    preset: str
    world: str
    snr_db: float
    category: str
    decision: str
    reasons: tuple[str, ...]
    dwells_used: int
    dwells: int
    llr: float


def run_tracks(preset: str = "paper", snrs: tuple[float, ...] = DEFAULT_TRACK_SNRS, n: int = 20,
               max_dwells: int = 10, seed: int = 7, sprt: Any = None,
               progress: Callable[[int], None] | None = None, world: str = "training") -> list[TrackTrial]:
    """n genuine and n type-spoof tracks of up to `max_dwells` dwells per SNR, each decided by
    `authn.track.decide_track` (the real Checker and policy; in memory, no audit)."""
    from authn.track import Sprt, decide_track

    sprt = sprt or Sprt()
    slugs = list(shipped_profiles())
    trials = []
    with tempfile.TemporaryDirectory() as tmp:
        checker = _checker(tmp)
        for s_idx, snr in enumerate(snrs):
            for c_idx, cat in enumerate(TRACK_CATEGORIES):
                rng = np.random.default_rng([seed, s_idx, c_idx, 37])
                for i in range(n):
                    flies, claims = _pair(cat, i, slugs)
                    scene = _scene(rng, flies, snr)
                    az, base = float(rng.uniform(0.0, 360.0)), int(rng.integers(2**31 - max_dwells))
                    start = datetime.now(timezone.utc)
                    dwells = [_lazy_dwell(scene, preset, base + j, bench_serial(claims), az, start, j, world)
                              for j in range(max_dwells)]
                    out = decide_track(checker, dwells, None, sprt)
                    trials.append(TrackTrial(preset, world, float(snr), cat, out.decision, tuple(out.reasons),
                                             out.dwells_used, max_dwells, out.llr))
                    if progress:
                        progress(1)
    return trials


def _lazy_dwell(scene: Scene, preset: str, seed: int, serial: str, az: float, start: datetime, j: int,
                world: str = "training", spacing_s: float = DWELL_SPACING_S, broadcast: Broadcast | None = None) -> Any:
    """Dwell j of a track (starts `spacing_s` apart), simulated on first use (its header needs the
    Remote ID, which the simulator writes beside the IQ) and kept for the full read; `broadcast`:
    its Remote ID where not plain `serial`'s."""
    from authn.track import Dwell

    cache: dict[str, Any] = {}

    def rec() -> Recording:
        if "rec" not in cache:
            sc = scene.model_copy(update={"range_m": max(1.0, scene.range_m + scene.radial_speed_mps * j * spacing_s)})
            when = start + timedelta(seconds=j * spacing_s)
            cache["rec"] = track_recordings(sc, preset, [seed], serial, az, when, world=world, broadcast=broadcast)[0]
        return cache["rec"]

    def header() -> Any:
        return Dwell.recording(rec(), f"dwell_{j:03d}").header()

    return Dwell(f"dwell_{j:03d}", header, lambda: (rec(), ""))


def summarise_tracks(trials: list[TrackTrial]) -> list[dict[str, Any]]:
    """Per (preset, world, SNR, category): right decisions, inconclusive share and dwells per decision."""
    groups: dict[tuple[str, str, float, str], list[TrackTrial]] = {}
    for t in trials:
        groups.setdefault((t.preset, t.world, t.snr_db, t.category), []).append(t)
    rows = []
    for (preset, world, snr, cat), ts in sorted(groups.items()):
        want = "accept" if cat == "genuine" else "reject"
        used = [t.dwells_used for t in ts]
        rows.append({"preset": preset, "world": world, "snr_db": snr, "category": cat, "tracks": len(ts),
                     "right": round(sum(is_right(want, t.decision) for t in ts) / len(ts), 4),
                     "inconclusive": round(sum(t.decision == "inconclusive" for t in ts) / len(ts), 4),
                     "median_dwells": statistics.median(used), "mean_dwells": round(statistics.fmean(used), 3),
                     "max_dwells": ts[0].dwells})
    return rows
