"""How far any per-dwell scoring can reach: a learner fitted on a world's own dwells (docs/tracks.md,
"What any per-dwell scoring can reach").

The track accuracy targets (`lab.bench.track_accuracy.TARGETS`) ask genuine tracks of the held-out world
to be accepted at 95-97 %. Whether a better estimator or scoring could get there is measured here with
an oracle far stronger than any deployed bundle: gradient-boosted trees fitted, per fold, on thousands
of the world's *own* dwells (scenes disjoint between folds; a site enrols 30 recordings per airframe),
given today's feature vector and a raw view of the target's slow time (`dwell_view`). Its out-of-fold
probabilities become one calibrated LLR per ordered pair (genuine A against an impostor B claiming A:
Platt-scaled, cross fitted, classes balanced), which is what the sequential test could add per dwell at
best with this much knowledge of the world. Tracks are then walked by `authn.sprt.Sprt` (the check's own
bounds, cap and discount) over each scene's dwells drawn with replacement, and the within-scene
correlation of the oracle's LLRs is measured beside it.

    python -m lab.bench.reach --world heldout --snr 10 --snr 0 --scenes 200 --dwells 5 --workers 2
    python -m lab.bench.reach ... --per-class 30 --inputs "envelope autocorrelation" --cache dwells.json

`--per-class N` fits on N single dwells per airframe (what a site enrolling N recordings has);
`--inputs` names the oracle's inputs, parts of the view among them (the ablation); `--cache` keeps the
rendered dwells for the next run; `--transfer INPUTS` fits on the training world (or `--fit-world`:
another, or a union such as training+randomised, the training simulator with each scene's nuisances
drawn) and scores the other worlds (what a shipped bundle must do). The track EER column is what any
rule on a track's mean LLR could reach under a random-effects model of the dwells (`track_eer`),
beside what the check's test does.

Scenes are drawn as `lab.bench.track_accuracy` draws them (another seed: no scene of the track accuracy run is
fitted on); nothing here ships or tunes anything that ships.
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass
from datetime import datetime, timezone

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

#: A genuine track's dwells in 2 s of back-to-back `paper` dwells (lab.bench.track_accuracy).
TRACK_DWELLS = 75
#: STFT of the view: frames of this many chirps, a hop of a quarter.
VIEW_WIN = 32
#: Envelope spectrum kept up to this rate (Hz; paper flash rates are 66-140 Hz, harmonics above).
VIEW_MAX_HZ = 700.0
#: Envelope autocorrelation sampled at this many lags over 1-30 ms (one to three flash periods).
VIEW_LAGS = 60
_TINY = 1e-30
#: A class's spread is floored here (a point mass) in the normal EER.
_TINY_SD = 1e-9
#: Worlds a dwell is rendered in.
RENDER_WORLDS = ("heldout", "training", "randomised")
#: Fits on fewer rows than this use a random forest instead of boosting.
SMALL_FIT = 600


def dwell_view(iq: np.ndarray, pri_s: float) -> np.ndarray:
    """What a learner sees beyond the feature vector, from an IF cube (chirps x samples): the
    strongest range bin +- 1 as slow time, its STFT power with the body line centred, and three
    scale-invariant summaries: the Doppler profile (log over its mean), the log spectrum of the
    flash envelope (power off the body line, over its mean; 4-bin means to `VIEW_MAX_HZ`) and the
    envelope's normalised autocorrelation at `VIEW_LAGS` lags. float32."""
    x = np.asarray(iq).astype(np.complex128)
    x = x - x.mean(axis=0, keepdims=True)
    spec = np.fft.fft(x * np.hanning(x.shape[1]), axis=1)
    prof = (np.abs(spec) ** 2).mean(axis=0)
    prof[0] = prof[-1] = 0.0
    peak = int(np.argmax(prof))
    slow = spec[:, max(0, peak - 1):peak + 2]
    frames = sliding_window_view(slow, VIEW_WIN, axis=0)[::VIEW_WIN // 4]  # (frames, cols, win)
    power = (np.abs(np.fft.fft(frames * np.hanning(VIEW_WIN), axis=-1)) ** 2).sum(axis=1)
    power = np.roll(power, VIEW_WIN // 2 - int(np.argmax(power.mean(axis=0))), axis=1)
    doppler = np.log(np.maximum(power.mean(axis=0), _TINY) / max(float(power.mean()), _TINY))
    off = np.ones(VIEW_WIN, dtype=bool)
    off[VIEW_WIN // 2 - 2:VIEW_WIN // 2 + 3] = False
    env = np.log(np.maximum(power[:, off].sum(axis=1), _TINY))
    env = (env - env.mean()) * np.hanning(env.size)
    step = VIEW_WIN // 4 * pri_s
    s = np.abs(np.fft.rfft(env, 1024)) ** 2
    s = np.log(s / max(float(s.mean()), _TINY) + 1e-6)[np.fft.rfftfreq(1024, step) < VIEW_MAX_HZ]
    s = s[:s.size // 4 * 4].reshape(-1, 4).mean(axis=1)
    ac = np.correlate(env, env, "full")[env.size - 1:]
    ac = ac / ac[0] if ac[0] > 0 else np.zeros_like(ac)
    acs = np.interp(np.linspace(0.001, 0.03, VIEW_LAGS), np.arange(ac.size) * step, ac, right=0.0)
    return np.concatenate([doppler, s, acs]).astype(np.float32)


@dataclass(frozen=True)
class RenderedDwell:
    """One genuine dwell as the oracle sees it: today's feature vector (by name) and `dwell_view`."""

    world: str
    snr_db: float
    flies: str
    scene: int
    features: list[float]
    view: list[float]


def _render(job: tuple) -> list[RenderedDwell]:
    """The dwells of one genuine scene of `flies` (drawn as the track accuracy run draws them)."""
    from lab.bench.decisions import bench_serial
    from lab.bench.track import track_recordings
    from lab.bench.track_accuracy import _scene_and_draws
    from signatures.dsp.extraction import extract
    from signatures.radar import get_preset

    world, snr, seed, p_idx, flies, i, k = job
    pre = get_preset("paper")
    scene, az, base = _scene_and_draws(seed, 0, snr, p_idx, i, flies)
    if world == "randomised":  # the training simulator, the scene's nuisances drawn once (a track repeats them)
        from signatures.sim.sampling import randomised

        scene = randomised(scene, np.random.default_rng([base, 41]))
    recs = track_recordings(scene, "paper", list(range(base, base + k)), bench_serial(flies), az,
                            spacing_s=pre.dwell_s, world="training" if world == "randomised" else world)
    out = []
    for rec in recs:
        f = asdict(extract(rec).features)
        out.append(RenderedDwell(world, snr, flies, i, [float(f[n]) for n in sorted(f)],
                         dwell_view(rec.iq, rec.config.pri_s).tolist()))
    return out


def render(world: str, snr: float, scenes: int, dwells: int, seed: int, workers: int) -> list[RenderedDwell]:
    """`scenes` genuine scenes of each shipped airframe, `dwells` back-to-back dwells each."""
    from lab.bench.track_accuracy import pairs

    jobs = [(world, snr, seed, p_idx, flies, i, dwells)
            for p_idx, (cat, flies, _claims, _why) in enumerate(pairs()) if cat == "genuine" for i in range(scenes)]
    if workers <= 1:
        return [d for j in jobs for d in _render(j)]
    with ProcessPoolExecutor(workers) as ex:
        return [d for ds in ex.map(_render, jobs, chunksize=4) for d in ds]


def per_airframe(rows: np.ndarray, airframes: np.ndarray, k: int, rng: np.random.Generator) -> np.ndarray:
    """At most `k` of `rows` of each airframe, drawn at random (a site enrols k recordings of each)."""
    return np.concatenate([rng.permutation(rows[airframes[rows] == a])[:k] for a in sorted(set(airframes[rows]))])


def out_of_fold(X: np.ndarray, y: np.ndarray, groups: np.ndarray, folds: int = 5, share: float = 1.0, seed: int = 0,
                per_class: int | None = None, first: np.ndarray | None = None,
                airframes: np.ndarray | None = None) -> tuple[np.ndarray, list[str]]:
    """Out-of-fold class probabilities of gradient-boosted trees (a random forest below
    `SMALL_FIT` rows, where boosting's leaves of 20 are too coarse), scenes never split across folds;
    `share` < 1 fits each fold on that share of its training scenes (the learning curve);
    `per_class` fits it on that many training scenes of each class, one dwell each (the rows where
    `first` is true): what a site enrolling `per_class` recordings per airframe has (per entry of
    `airframes` where classes group several airframes; default: per class)."""
    from sklearn.ensemble import HistGradientBoostingClassifier, RandomForestClassifier
    from sklearn.model_selection import GroupKFold

    classes = sorted(set(y.tolist()))
    p = np.zeros((y.size, len(classes)))
    rng = np.random.default_rng(seed)
    for tr, te in GroupKFold(folds).split(X, y, groups):
        if share < 1.0:
            keep = rng.permutation(np.unique(groups[tr]))[:max(2, int(round(share * np.unique(groups[tr]).size)))]
            tr = tr[np.isin(groups[tr], keep)]
        if per_class is not None:
            tr = tr[first[tr]] if first is not None else tr
            tr = per_airframe(tr, y if airframes is None else airframes, per_class, rng)
        model = (HistGradientBoostingClassifier(max_iter=300, learning_rate=0.05, l2_regularization=1.0,
                                                random_state=seed) if tr.size >= SMALL_FIT else
                 RandomForestClassifier(500, min_samples_leaf=2, random_state=seed, n_jobs=2)).fit(X[tr], y[tr])
        cols = [classes.index(c) for c in model.classes_]
        p[np.ix_(te, cols)] = model.predict_proba(X[te])
    return p, classes


def _log_ratio(p: np.ndarray, classes: list[str], a: str, b: str) -> np.ndarray:
    """log p(a) - log p(b) per row, the probabilities floored at 1e-4."""
    return np.log(np.clip(p[:, classes.index(a)], 1e-4, 1.0)) - np.log(np.clip(p[:, classes.index(b)], 1e-4, 1.0))


def pair_llr(p: np.ndarray, classes: list[str], y: np.ndarray, groups: np.ndarray, a: str, b: str,
             folds: int = 5) -> tuple[np.ndarray, np.ndarray]:
    """Calibrated per-dwell LLR of "A" against "B" on the dwells of A and B: the log ratio of the
    two probabilities, Platt-scaled by a logistic regression fitted on the other folds' scenes with
    the classes weighted equally (so that it is a likelihood ratio, not posterior odds). Returns
    (llr, is_a) over the selected dwells, in data order."""
    from sklearn.linear_model import LogisticRegression
    from sklearn.model_selection import GroupKFold

    sel = (y == a) | (y == b)
    raw = _log_ratio(p[sel], classes, a, b)
    is_a = (y[sel] == a).astype(int)
    llr = np.zeros_like(raw)
    for tr, te in GroupKFold(folds).split(raw, is_a, groups[sel]):
        lr = LogisticRegression(C=1e4, class_weight="balanced").fit(raw[tr, None], is_a[tr])
        llr[te] = lr.decision_function(raw[te, None])
    return llr, is_a.astype(bool)


def scene_icc(llr: np.ndarray, scenes: np.ndarray, cap: float) -> float:
    """Intra-class correlation of the capped LLRs within scenes (`lab.bench.track.icc`)."""
    from lab.bench.track import icc

    v = np.clip(llr, -cap, cap)
    return icc([v[scenes == s].tolist() for s in np.unique(scenes)])


def _components(x: np.ndarray, scenes: np.ndarray) -> tuple[float, float, float]:
    """(mean, between-scene variance, within-scene variance) of a one-way random-effects layout."""
    groups = [x[scenes == s] for s in np.unique(scenes)]
    within = float(np.mean([g.var(ddof=1) for g in groups if g.size > 1]))
    k = float(np.mean([g.size for g in groups]))
    between = max(0.0, float(np.var([g.mean() for g in groups], ddof=1)) - within / k)
    return float(x.mean()), between, within


def _eer_normal(mu_a: float, sd_a: float, mu_b: float, sd_b: float) -> float:
    """Equal error rate of a threshold between N(mu_a, sd_a) (above) and N(mu_b, sd_b) (below). A
    spread of 0 (every capped LLR at the cap) is a point mass: floored, not divided by."""
    phi = lambda z: 0.5 * math.erfc(-z / math.sqrt(2.0))  # noqa: E731
    sd_a, sd_b = max(sd_a, _TINY_SD), max(sd_b, _TINY_SD)
    lo, hi = min(mu_a, mu_b) - 10 * max(sd_a, sd_b), max(mu_a, mu_b) + 10 * max(sd_a, sd_b)
    for _ in range(200):  # miss(t) rises and false accept(t) falls with t: bisect on their difference
        t = 0.5 * (lo + hi)
        if phi((t - mu_a) / sd_a) < 1.0 - phi((t - mu_b) / sd_b):
            lo = t
        else:
            hi = t
    return phi((lo - mu_a) / sd_a)


def track_eer(llr: np.ndarray, is_a: np.ndarray, scenes: np.ndarray, cap: float, dwells: int = TRACK_DWELLS) -> float:
    """The equal error rate any rule on the mean capped LLR of a track of `dwells` dwells could reach,
    genuine against impostor tracks, in the random-effects model of each class's dwells (a scene's
    bias, its between-scene variance, repeats in every dwell; the within-scene part averages out):
    the track mean is N(mean, between + within / dwells). No discount or bound is assumed."""
    x = np.clip(llr, -cap, cap)
    ma, ba, wa = _components(x[is_a], scenes[is_a])
    mb, bb, wb = _components(x[~is_a], scenes[~is_a])
    return _eer_normal(ma, math.sqrt(ba + wa / dwells), mb, math.sqrt(bb + wb / dwells))


def walk_scenes(llr: np.ndarray, scenes: np.ndarray, rho: float, seed: int = 0,
                dwells: int = TRACK_DWELLS) -> list[tuple[str, int]]:
    """One track per scene: `dwells` of the scene's LLRs drawn with replacement, walked by the
    check's sequential test (`authn.sprt.Sprt`, default bounds and cap, correlation `rho`)."""
    from authn.sprt import Sprt

    sprt = Sprt(correlation=rho)
    rng = np.random.default_rng(seed)
    return [sprt.walk([(float(x), True) for x in rng.choice(llr[scenes == s], dwells)]) for s in np.unique(scenes)]


@dataclass(frozen=True)
class PairReach:
    world: str
    snr_db: float
    inputs: str
    fitted_on: str  # the share of each fold's training scenes, or "N dwells" per class
    genuine: str
    impostor: str
    mean_genuine: float
    mean_impostor: float
    icc_genuine: float
    accepted: float
    accepted_rho_measured: float
    rejected: float
    median_dwells: float
    track_eer: float
    track_dwells: int = TRACK_DWELLS


def _without_envelope(d: RenderedDwell) -> list[float]:
    """The feature vector without the flash envelope's autocorrelation (what it was before that
    was added; `RenderedDwell.features` are in sorted name order)."""
    from signatures.dsp.feature_vector import ENVELOPE_FEATURES, FEATURE_NAMES

    return [v for n, v in zip(sorted(FEATURE_NAMES), d.features) if n not in ENVELOPE_FEATURES]


_PARTS = {"features": lambda d: d.features, "features without envelope": _without_envelope, "view": lambda d: d.view,
          "features+view": lambda d: d.features + d.view, "doppler": lambda d: d.view[:VIEW_WIN],
          "envelope spectrum": lambda d: d.view[VIEW_WIN:-VIEW_LAGS],
          "envelope autocorrelation": lambda d: d.view[-VIEW_LAGS:],
          "features+autocorrelation": lambda d: d.features + d.view[-VIEW_LAGS:]}


def _layout(ds: list[RenderedDwell], inputs: str, groups: dict[str, str] | None = None):
    """(X, labels, scene names) of dwells."""
    X = np.nan_to_num(np.array([_PARTS[inputs](d) for d in ds], dtype=np.float64))
    y = np.array([(groups or {}).get(d.flies, d.flies) for d in ds])
    return X, y, np.array([f"{d.flies}/{d.scene}" for d in ds])


def _pair_row(world: str, snr: float, inputs: str, fitted_on: str, a: str, b: str, llr: np.ndarray,
              is_a: np.ndarray, sc: np.ndarray, dwells: int = TRACK_DWELLS) -> PairReach:
    from authn.track import DWELL_CAP_NATS, DWELL_CORRELATION

    rho_g = scene_icc(llr[is_a], sc[is_a], DWELL_CAP_NATS)
    gen = walk_scenes(llr[is_a], sc[is_a], DWELL_CORRELATION, dwells=dwells)
    gen_m = walk_scenes(llr[is_a], sc[is_a], min(0.95, max(0.0, rho_g)), dwells=dwells)
    imp = walk_scenes(llr[~is_a], sc[~is_a], DWELL_CORRELATION, dwells=dwells)
    capped = np.clip(llr, -DWELL_CAP_NATS, DWELL_CAP_NATS)
    return PairReach(world, snr, inputs, fitted_on, a, b, round(float(capped[is_a].mean()), 3),
                     round(float(capped[~is_a].mean()), 3), round(rho_g, 3),
                     float(np.mean([d == "accept" for d, _ in gen])), float(np.mean([d == "accept" for d, _ in gen_m])),
                     float(np.mean([d != "accept" for d, _ in imp])), float(np.median([n for _, n in gen])),
                     round(track_eer(llr, is_a, sc, DWELL_CAP_NATS, dwells), 4), dwells)


def _by_world_snr(dwells: list[RenderedDwell]):
    key = lambda d: (d.world, d.snr_db)  # noqa: E731
    return itertools.groupby(sorted(dwells, key=lambda d: (d.world, -d.snr_db)), key=key)


def reach(dwells: list[RenderedDwell], inputs: str = "features+view", shares: tuple[float, ...] = (1.0,),
          groups: dict[str, str] | None = None, per_class: int | None = None,
          track_dwells: int = TRACK_DWELLS) -> list[PairReach]:
    """Per ordered pair of (grouped) airframes: the oracle's per-dwell evidence and the tracks it
    would decide. `groups` maps airframes to a group label (e.g. two radar-confusable models to one)."""
    out = []
    for (world, snr), group in _by_world_snr(dwells):
        ds = list(group)
        X, y, scenes = _layout(ds, inputs, groups)
        scene_ids = np.unique(scenes, return_inverse=True)[1]
        first = np.r_[True, scenes[1:] != scenes[:-1]]  # a scene's first dwell (they are rendered in order)
        airframes = np.array([d.flies for d in ds])  # one class may group several (`groups`)
        for share in shares:
            p, classes = out_of_fold(X, y, scene_ids, share=share, per_class=per_class, first=first,
                                     airframes=airframes)
            for a, b in itertools.permutations(classes, 2):
                llr, is_a = pair_llr(p, classes, y, scene_ids, a, b)
                out.append(_pair_row(world, snr, inputs, f"{per_class} dwells" if per_class else f"{share:.0%}",
                                     a, b, llr, is_a, scenes[(y == a) | (y == b)], track_dwells))
    return out


def transfer(dwells: list[RenderedDwell], inputs: str, fit_world: str = "training",
             track_dwells: int = TRACK_DWELLS) -> list[PairReach]:
    """The same learner fitted on all of `fit_world`'s dwells at an SNR (worlds joined by "+": their
    union) and scored on every other world's at that SNR: whether what it learned holds in a world it
    never saw (what a shipped bundle must do). The LLR is the log ratio of the two probabilities,
    uncalibrated (a calibration would need the test world), so only its EER column is comparable with
    the oracle's."""
    from sklearn.ensemble import HistGradientBoostingClassifier

    groups = {key: list(ds) for key, ds in _by_world_snr(dwells)}
    fit = fit_world.split("+")
    out = []
    for (world, snr), ds in groups.items():
        if world in fit or any((w, snr) not in groups for w in fit):
            continue
        Xf, yf, _ = _layout([d for w in fit for d in groups[(w, snr)]], inputs)
        X, y, scenes = _layout(ds, inputs)
        model = HistGradientBoostingClassifier(max_iter=300, learning_rate=0.05, l2_regularization=1.0,
                                               random_state=0).fit(Xf, yf)
        p, classes = model.predict_proba(X), list(model.classes_)
        for a, b in itertools.permutations(classes, 2):
            sel = (y == a) | (y == b)
            llr = _log_ratio(p[sel], classes, a, b)
            out.append(_pair_row(world, snr, inputs, f"{fit_world} world", a, b, llr, y[sel] == a, scenes[sel],
                                 track_dwells))
    return out


def read_caches(paths: list[str], worlds: list[str], snrs: list[float]) -> list[RenderedDwell]:
    """The dwells of `worlds` at `snrs` held by the caches at `paths` (the first cache holding a
    (world, SNR) supplies it)."""
    out: list[RenderedDwell] = []
    for path in paths:
        with open(path) as fh:
            got = [RenderedDwell(**d) for d in json.load(fh) if d["world"] in worlds and d["snr_db"] in snrs]
        have = {(d.world, d.snr_db) for d in out}
        out += [d for d in got if (d.world, d.snr_db) not in have]
    return out


def table(rows: list[PairReach]) -> list[str]:
    lines = ["| world | SNR dB | inputs | fitted on | genuine | impostor claiming it | mean LLR genuine / impostor "
             "| ICC genuine | genuine tracks accepted (rho 0.2 / measured) | impostor tracks rejected "
             "| median dwells | track EER, any rule (dwells) |", "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r.world} | {r.snr_db:g} | {r.inputs} | {r.fitted_on} | {r.genuine} | {r.impostor} | "
                     f"{r.mean_genuine:+.2f} / {r.mean_impostor:+.2f} | {r.icc_genuine:.2f} | {r.accepted:.0%} / "
                     f"{r.accepted_rho_measured:.0%} | {r.rejected:.0%} | {r.median_dwells:g} | "
                     f"{r.track_eer:.1%} ({r.track_dwells}) |")
    return lines


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m lab.bench.reach", description=__doc__.splitlines()[0])
    ap.add_argument("--world", action="append", choices=RENDER_WORLDS,
                    help="worlds to render or read (repeatable; randomised: the training simulator with each "
                         "scene's nuisances drawn, signal-model.md)")
    ap.add_argument("--snr", action="append", type=float)
    ap.add_argument("--scenes", type=int, default=200, help="genuine scenes per airframe, world and SNR")
    ap.add_argument("--dwells", type=int, default=5, help="back-to-back dwells per scene")
    ap.add_argument("--seed", type=int, default=11, help="scene seed (the track accuracy run uses 7)")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--inputs", action="append", choices=tuple(_PARTS),
                    help="what the oracle is given (repeatable; the last three are parts of the view)")
    ap.add_argument("--share", action="append", type=float,
                    help="learning curve: the share of each fold's scenes fitted on")
    ap.add_argument("--per-class", type=int, action="append", default=[],
                    help="also fit on this many scenes per airframe, one dwell each (a site's enrolment size)")
    ap.add_argument("--transfer", action="append", default=[], choices=tuple(_PARTS),
                    help="also fit on the training world and score the others with these inputs (repeatable)")
    ap.add_argument("--fit-world", action="append", default=[], metavar="W[+W]",
                    help="the world(s) --transfer fits on (repeatable; default training; a+b: their union)")
    ap.add_argument("--group", action="append", default=[], metavar="A,B",
                    help="also report with these airframes as one class (repeatable; with --per-class, each airframe "
                         "fitted on that many)")
    ap.add_argument("--track-dwells", type=int, default=TRACK_DWELLS,
                    help=f"dwells per track (default {TRACK_DWELLS}: 2 s of `paper` dwells; a site decides on 8)")
    ap.add_argument("--cache", action="append", default=[],
                    help="dwells cache (JSON, repeatable): those present are read; the (world, SNR) they lack are "
                         "rendered and written to the first one absent")
    ap.add_argument("--json", help="write the rows to this file")
    a = ap.parse_args(argv)
    from signatures.dsp.feature_vector import FEATURE_NAMES

    if a.track_dwells < 1:
        ap.error(f"--track-dwells {a.track_dwells}: at least 1")
    for spec in a.fit_world:
        unknown = [w for w in spec.split("+") if w not in (a.world or ["heldout"])]
        if unknown:
            ap.error(f"--fit-world {spec}: {', '.join(unknown)} is not among the --world given")
    t0 = time.perf_counter()
    print(f"# {' '.join(['python -m lab.bench.reach', *(argv if argv is not None else sys.argv[1:])])}")
    print(f"# {datetime.now(timezone.utc).date()}, {os.cpu_count()} cores")
    worlds, snrs = a.world or ["heldout"], a.snr or [10.0, 0.0]
    dwells = read_caches([c for c in a.cache if os.path.exists(c)], worlds, snrs)
    if any(len(d.features) != len(FEATURE_NAMES) for d in dwells):
        ap.error(f"a cache holds another feature vector than today's {len(FEATURE_NAMES)}: delete it")
    have = {(d.world, d.snr_db) for d in dwells}
    rendered = [d for w in worlds for s in snrs if (w, float(s)) not in have
                for d in render(w, s, a.scenes, a.dwells, a.seed, a.workers)]
    new_cache = [c for c in a.cache if not os.path.exists(c)]
    if rendered and new_cache:
        with open(new_cache[0], "w") as fh:
            json.dump([asdict(d) for d in rendered], fh)
    dwells += rendered
    print(f"# {len(dwells)} dwells rendered/read in {time.perf_counter() - t0:.0f} s", file=sys.stderr)
    oracle = a.inputs or ([] if a.transfer else ["features", "features+view"])  # --transfer alone: its rows only
    rows = [r for inputs in oracle
            for r in reach(dwells, inputs, tuple(a.share or [1.0]), track_dwells=a.track_dwells)]
    for inputs in a.transfer:
        for fit_world in a.fit_world or ["training"]:
            rows += transfer(dwells, inputs, fit_world, track_dwells=a.track_dwells)
    for k in a.per_class:
        rows += reach(dwells, "features+view", (1.0,), per_class=k, track_dwells=a.track_dwells)
    for spec in a.group:
        members = spec.split(",")
        for k in [None, *a.per_class]:
            rows += reach(dwells, "features+view", (1.0,), {m: "+".join(members) for m in members}, per_class=k,
                          track_dwells=a.track_dwells)
    print("\n".join(table(rows)))
    if a.json:
        with open(a.json, "w") as fh:
            json.dump([asdict(r) for r in rows], fh)
    print(f"# {time.perf_counter() - t0:.0f} s", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
