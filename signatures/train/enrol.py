"""Site enrolment: adapt a model bundle to the site's own radar from its recorded genuine flights.

Why: every learned part of a bundle was fitted to simulated returns, and no simulator is the
site's radar (docs/enrolment.md). A site flies each registered airframe past
its radar; these recordings, labelled with the registered model, build a *site bundle* that
`authn check` then uses for that waveform ahead of the shipped one.

Method (fixed a priori, measured in docs/benchmarks.md "Site enrolment"):

1. a simulated base set for the waveform (`N_SIM` returns of the shipped profiles plus the
   enrolled ones, bird and none: what keeps the classes the site cannot fly, cached);
2. the Random Forest refitted on base + site returns, the site's returns weighted so that each
   enrolled model's site returns weigh `SITE_SHARE` of that model's total (site data dominates
   where it exists, the simulator fills the rest of the feature space);
3. K-fold cross-validation over the site recordings (the base set always in training): the
   out-of-fold probabilities calibrate the temperature (over a bounded range,
   `classifiers.bounded_temperature`: the ill-posed maximum-likelihood temperature of a
   perfectly separated set is avoided), give the confusion
   matrix, and score every recording against its own model (genuine) and against every other
   enrolled model (impostor) with the check's own 1:1 verification (`signatures.classify.verify`);
4. the verification threshold: the lowest LLR at which the cross-validated false-accept rate of
   the impostor claims is <= `FALSE_ACCEPT_TARGET` (reported; the policy applies 0 nats, see the
   card's `threshold.applied`);
5. radar-confusable pairs: enrolled pairs whose cross-validated pairwise false-accept rate at
   the applied threshold exceeds `CONFUSABLE_ERROR` (the policy then asks for a DRIP signature,
   `radar-confusable-unsigned`), of single dwells and of tracks (`separability.track_rates`: tracks of
   `TRACK_DWELLS` drawn from a model's cross-validated dwell scores, decided by the check's own
   sequential test, passed in as `sprt` since it lives above this layer), and every pair with
   fewer than `MIN_SEPARABLE_CLAIMS` cross-validated claims: too few to show radar can separate
   it, so fewer recordings never mean fewer signatures asked for;
6. optionally (`physics_bands`, `models enrol --site-bands`; by default only with one model: with
   several, measured not to help on the held-out world, docs/enrolment.md) each enrolled model's
   rate (a mixture of modes), rotor and blade bands from its site recordings (`site_bands`), today's
   `signatures.classify.verify` bands the prior; out of fold in the cross-validation (each recording verified
   with the bands of the other folds), and the open set's rate test takes them.

Every registered or shipped profile not enrolled is simulated in the waveform (`signatures.train.impostors`):
the other side of each enrolled model's pairs, so that one model enrols on its own.

The bundle is written to a temporary folder beside its destination and renamed into place: an
interrupted enrolment leaves nothing half-written, and the active bundle switches only after
(`signatures.classify.inference.set_active`). scikit-learn is imported here only: the check never runs this.
"""

from __future__ import annotations

import os
import shutil
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from datetime import datetime, timezone
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from signatures.profiles import UavProfile
from signatures.radar import Preset
from signatures.train.impostors import N_OTHERS
from signatures.train.separability import (CALIBRATION_GAIN, CONFUSABLE_ERROR, MIN_SEPARABLE_CLAIMS, TRACK_DRAWS,
                                           TRACK_DWELLS, DwellScore, calibration_pays, mean_or_none, pair_cards,
                                           rate_or_none, separation, signatures_needed, single_confusable,
                                           threshold_at, track_confusable, track_rates)
from signatures.train.site_bands import BAND_PRIOR_WEIGHT, site_bands
from signatures.train.site_samples import MIN_RECORDINGS, EnrolError, SiteSample, site_arrays

if TYPE_CHECKING:
    from signatures.classify.calibration import Calibration
    from signatures.train.dataset import Dataset
    from signatures.classify.openset import PhysicsCheck

__all__ = ["ENROL_FORMAT", "FALSE_ACCEPT_TARGET", "N_SIM", "ONE_MODEL_BANDS", "SITE_SHARE", "EnrolOptions",
           "check_counts", "default_name", "enrol"]

#: The false-accept target the reported verification threshold is chosen at.
FALSE_ACCEPT_TARGET = 0.01
#: Site returns' share of each enrolled model's training weight.
SITE_SHARE = 0.8
#: Simulated base returns (cached per waveform and profile set).
N_SIM = 1500
#: Site physics bands (`site_bands`) by default where one model is enrolled: its recordings are the
#: only measurement of that airframe on this radar, and no other enrolled model's band can be blurred
#: into it (with several, measured not to help: docs/enrolment.md).
ONE_MODEL_BANDS = True
CV_FOLDS = 5
ENROL_FORMAT = "uav-radar-authn/site-enrolment/1"


def _oof(fit: Callable[[np.ndarray], Any], predict: Callable[[Any, np.ndarray], np.ndarray],
         y_site: np.ndarray, n_folds: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Out-of-fold predictions over the site samples (stratified folds), and each sample's fold."""
    from sklearn.model_selection import StratifiedKFold

    out: np.ndarray | None = None
    fold_of = np.zeros(len(y_site), dtype=np.int64)
    folds = StratifiedKFold(n_splits=n_folds, shuffle=True, random_state=seed)
    for k, (train_idx, test_idx) in enumerate(folds.split(np.zeros(len(y_site)), y_site)):
        model = fit(train_idx)
        p = predict(model, test_idx)
        if out is None:
            out = np.zeros((len(y_site), p.shape[1]))
        out[test_idx] = p
        fold_of[test_idx] = k
    assert out is not None
    return out, fold_of


def _fit_rf(X: np.ndarray, y: np.ndarray, w: np.ndarray, seed: int, n_jobs: int) -> Any:
    from signatures.train.classifiers import make_rf

    model = make_rf(seed)
    model.set_params(randomforestclassifier__n_jobs=n_jobs)
    return model.fit(X, y, randomforestclassifier__sample_weight=w)


def _weights(y_sim: np.ndarray, y_site: np.ndarray, n_cls: int) -> np.ndarray:
    """Per-site-sample weights: each enrolled class's site returns weigh SITE_SHARE of its total."""
    w = np.ones(len(y_site))
    for c in range(n_cls):
        m = y_site == c
        if m.any():
            n_sim = max(int(np.sum(y_sim == c)), 1)
            w[m] = SITE_SHARE / (1.0 - SITE_SHARE) * n_sim / m.sum()
    return w


def _verification(samples: Sequence[SiteSample], proba: np.ndarray, known: np.ndarray, classes: tuple[str, ...],
                  profiles: dict[str, UavProfile], enrolled: list[str], max_tip: float,
                  bands: Callable[[int], dict[str, Any] | None] = lambda i: None, rows: list | None = None,
                  ) -> list[tuple[str, str, float, dict[str, float]]]:
    """Cross-validated 1:1 verification claims (flown, claimed, LLR, terms; `_scored` reads them):
    each detected recording against its own model (genuine) and against every other model of
    `enrolled` (the models claimed). `rows`, where given, receives each claim's (recording index,
    flown, claimed, RawTerms)."""
    from signatures.features import FEATURE_NAMES
    from signatures.classify.verify import bands_from, verify

    claims: list[tuple[str, str, float, dict[str, float]]] = []
    for i, s in enumerate(samples):
        if not s.detected:
            continue
        feats = {**dict(zip(FEATURE_NAMES, (float(v) for v in s.features))), **s.physics}
        probs = dict(zip(classes, (float(v) for v in proba[i])))
        for claimed in enrolled:
            v = verify(feats, profiles[claimed], probs, max_tip, known=bool(known[i]),
                       bands=bands_from(bands(i), claimed))
            claims.append((s.model, claimed, v.llr, v.terms))
            if rows is not None:
                rows.append((i, s.model, claimed, v.raw))
    return claims


def _scored(claims: Sequence[tuple[str, str, float, dict[str, float]]],
            ) -> tuple[list[float], dict[tuple[str, str], list[float]], dict[tuple[str, str], list[DwellScore]]]:
    """Claims (flown, claimed, LLR, the terms that did not abstain) as the enrolment reads them:
    genuine LLRs, impostor LLRs per (flown, claimed), and every pair's claims as a track's dwells
    (`DwellScore`: None where nothing was verified)."""
    genuine: list[float] = []
    impostor: dict[tuple[str, str], list[float]] = {}
    dwells: dict[tuple[str, str], list[DwellScore]] = {}
    for flown, claimed, llr, terms in claims:
        if flown == claimed:
            genuine.append(llr)
        else:
            impostor.setdefault((flown, claimed), []).append(llr)
        dwells.setdefault((flown, claimed), []).append((llr, "physics" in terms) if terms else None)
    return genuine, impostor, dwells


def _calibrated(rows: Sequence[tuple[int, str, str, Any]], fold_of: np.ndarray, n_folds: int,
                extra: Sequence[tuple[int, str, str, Any]] = (),
                ) -> tuple[Any, list[float], dict[tuple[str, str], list[float]],
                           dict[tuple[str, str], list[DwellScore]]]:
    """The site's score calibration (`signatures.classify.calibration.fit` on every claim's out-of-fold raw
    terms), and the claims re-scored as `_scored` reads them, each recording's by a calibration
    fitted on the other folds' claims only (cross-fitted: no claim scores itself); `extra` claims
    (the simulated other profiles', never fitted on) by the calibration of all the rows."""
    from signatures.classify.calibration import fit

    raws = [r[3] for r in rows]
    gen = [r[1] == r[2] for r in rows]
    folds = np.array([int(fold_of[r[0]]) for r in rows])
    llrs = np.zeros(len(rows))
    terms: list[dict[str, float]] = [{} for _ in rows]
    for k in range(n_folds):
        out = folds != k
        cal_k = fit([r for r, o in zip(raws, out) if o], [g for g, o in zip(gen, out) if o])
        for j in np.flatnonzero(~out):
            terms[j] = cal_k.terms(raws[j])
            llrs[j] = sum(terms[j].values())
    cal = fit(raws, gen)
    more = [(flown, claimed, float(sum(t.values())), t) for _, flown, claimed, raw in extra for t in [cal.terms(raw)]]
    scored = _scored([(flown, claimed, float(llr), t) for (_, flown, claimed, _raw), llr, t in zip(rows, llrs, terms)]
                     + more)
    return (cal, *scored)


def _oof_unknown(phys: Any, classes: Sequence[str], X_site: np.ndarray, pred: np.ndarray, fold_of: np.ndarray,
                 fold_bands: dict[int, dict[str, Any]]) -> np.ndarray:
    """The open set's physical verdict on each site recording, out of fold like the verification:
    with the site rate bands of the other folds' recordings where bands are estimated."""
    unk = np.zeros(len(X_site), dtype=bool)
    for k in np.unique(fold_of):
        fk = fold_of == k
        bands = fold_bands.get(int(k))
        pk = phys.with_rate_bands(classes, {m: b["rate"] for m, b in bands.items()}) if bands else phys
        unk[fk] = pk.verdict(np.nan_to_num(X_site[fk].astype(np.float64)), pred[fk])[0]
    return unk


def _others(wf: Preset, others: Sequence[UavProfile], n: int, seed: int, workers: int,
            cache: Path | None | bool) -> list[SiteSample]:
    """The detected simulated returns of the profiles not enrolled (`signatures.train.impostors`), as samples."""
    from signatures.train.impostors import simulate_others

    if not others or n <= 0:
        return []
    rows = simulate_others(wf, others, n, seed, workers, cache)
    return [SiteSample(f"simulated:{m}:{i}", "", m, x, phys, det)
            for m, rs in rows.items() for i, (x, phys, det) in enumerate(rs) if det]


def check_counts(samples: Sequence[SiteSample], profiles: dict[str, UavProfile], duplicates: int = 0) -> None:
    """Refuse (EnrolError) what cannot be enrolled: an unknown model, fewer than MIN_RECORDINGS
    distinct recordings (or detections) of a model. One model is enough: the other profiles are
    simulated in the site's waveform (`signatures.train.impostors`). Recordings are counted by the
    SHA-256 of their bytes: copies of one flight are one recording. `duplicates`: how many
    copies the caller left out already (said in a refusal)."""
    enrolled = sorted({s.model for s in samples})
    unknown = [m for m in enrolled if m not in profiles]
    if unknown:
        raise EnrolError(f"unknown model {unknown[0]!r}: register its profile first (authn register --model ...)")
    note = f" ({duplicates} duplicate recording{'s' if duplicates != 1 else ''} ignored)" if duplicates else ""
    counts = {m: len({s.sha256 for s in samples if s.model == m}) for m in enrolled}
    short = {m: n for m, n in counts.items() if n < MIN_RECORDINGS}
    if short:
        m, n = next(iter(short.items()))
        raise EnrolError(f"model {m}: {n} recording{'s' if n != 1 else ''}, at least {MIN_RECORDINGS} per model "
                         f"needed{note}")
    if len({s.sha256 for s in samples}) < len(samples):
        raise EnrolError("the same recording (by SHA-256) is given more than once: enrol each flight once")
    det_counts = {m: sum(s.model == m and s.detected for s in samples) for m in enrolled}
    if any(n < MIN_RECORDINGS for n in det_counts.values()):
        m = next(m for m, n in det_counts.items() if n < MIN_RECORDINGS)
        raise EnrolError(f"model {m}: the radar detected a target in only {det_counts[m]} of its {counts[m]} "
                         f"recordings, at least {MIN_RECORDINGS} needed{note}")


@dataclass(frozen=True)
class EnrolOptions:
    """How one enrolment runs (`enrol`). `name`: the bundle's; `sources`: the names the recordings
    were given as; `previous`: the bundle it extends (`--add`); `seed`, `workers`, `n_sim` (simulated
    base returns), `cache`: as `signatures.train.dataset.generate`; `progress(phase, fraction done)`.
    `sprt`: the track check's sequential test (`authn.sprt.Sprt`: its `walk` and `to_json`), which
    gives the card its track-level pairwise errors (None: single dwells only; `authn models enrol`
    passes the check's default). `physics_bands`: re-estimate each enrolled model's rate, rotor and
    blade bands from the site recordings (`site_bands`; cross-validated like the rest); None: where
    one model is enrolled (`ONE_MODEL_BANDS`). `score_calibration`: verify with the score calibration
    fitted on the cross-validated terms (`signatures.classify.calibration`; always fitted and reported in the
    card): True applies it, False does not, None applies it where the site's cross-validated claims
    say it pays (`calibration_pays`). `n_others`: simulated returns of each profile not enrolled
    (`signatures.train.impostors`), the other side of its pairs. `carriers`: the carriers the recordings
    were made at (Hz -> recordings), for the card."""

    name: str
    sources: Sequence[str] = ()
    previous: str | None = None
    seed: int = 0
    workers: int = 2
    n_sim: int = N_SIM
    cache: Path | None | bool = None
    progress: Callable[[str, float], None] | None = None
    sprt: Any = None
    physics_bands: bool | None = None
    score_calibration: bool | None = None
    n_others: int = N_OTHERS
    carriers: dict[float, int] | None = None


def enrol(samples: Sequence[SiteSample], profiles: dict[str, UavProfile], waveform: Preset, dest: Path,
          options: EnrolOptions) -> dict[str, Any]:
    """Build the site bundle `dest` (must not exist) from `samples` (the site's labelled
    recordings, of `waveform`) on a simulated base set of `profiles` (every model the bundle
    knows: the shipped and the enrolled ones), as `options` say. Returns the card."""
    t0 = time.perf_counter()
    check_counts(samples, profiles)
    if dest.exists():
        raise EnrolError(f"{dest}: a bundle of that name exists (choose another --name)")
    run = _Run.of(samples, profiles, waveform, options)
    base = _base_set(run)
    folds = _cross_validate(run, base)
    open_set = _open_set(run, base, folds)
    scores = _scores(run, base, folds, open_set)
    run.say("fitting the site bundle", (folds.n + 1) / (folds.n + 2))
    card = _write_bundle(run, base, folds, open_set, scores, dest, t0)
    run.say("done", 1.0)
    return card


@dataclass(frozen=True)
class _Run:
    """One enrolment's inputs: the samples (`site`: those the radar detected), the models enrolled,
    whether their bands are re-estimated, the options."""

    samples: Sequence[SiteSample]
    site: list[SiteSample]
    profiles: dict[str, UavProfile]
    wf: Preset
    enrolled: list[str]
    physics_bands: bool
    opt: EnrolOptions

    @classmethod
    def of(cls, samples: Sequence[SiteSample], profiles: dict[str, UavProfile], wf: Preset,
           opt: EnrolOptions) -> _Run:
        enrolled = sorted({s.model for s in samples})
        bands = len(enrolled) == 1 and ONE_MODEL_BANDS if opt.physics_bands is None else opt.physics_bands
        return cls(samples, [s for s in samples if s.detected], profiles, wf, enrolled, bands, opt)

    def say(self, phase: str, frac: float) -> None:
        if self.opt.progress is not None:
            self.opt.progress(phase, frac)

    @property
    def det_counts(self) -> dict[str, int]:
        return {m: sum(s.model == m for s in self.site) for m in self.enrolled}


@dataclass(frozen=True)
class _Base:
    """What the forests learn from: the simulated base set and the site's returns (class feature
    columns `cols`, site weights), the simulated returns of the profiles not enrolled (`X_oth`),
    and the physical check of the waveform."""

    plist: tuple[UavProfile, ...]
    sim: Dataset
    others: list[SiteSample]
    classes: tuple[str, ...]
    names: list[str]
    cols: list[int]
    y_sim: np.ndarray
    X_site: np.ndarray
    y_site: np.ndarray
    X_oth: np.ndarray
    y_oth: np.ndarray
    X_all: np.ndarray
    y_all: np.ndarray
    w_all: np.ndarray
    phys: PhysicsCheck
    jitter: float
    tip_bin: float

    @property
    def n_cls(self) -> int:
        return len(self.classes)

    @property
    def n_s(self) -> int:
        return len(self.y_sim)

    @property
    def index(self) -> dict[str, int]:
        return {c: i for i, c in enumerate(self.classes)}


def _base_set(run: _Run) -> _Base:
    """Simulate the base set and the profiles not enrolled, and stack them with the site's returns."""
    from signatures.train.dataset import DatasetSpec, generate
    from signatures.classify.openset import physics_check
    from signatures.radar import C
    from signatures.sim.scene import Scene
    from signatures.train.training import (GEOMETRY_FEATURES, LEVEL_FEATURES, PHYS_MAX_REL_TOL, PHYS_MIN_FLASH_SCORE,
                                           PHYS_Z)

    opt, wf = run.opt, run.wf
    plist = tuple(run.profiles[k] for k in sorted(run.profiles))
    run.say("simulating the base set", 0.0)
    sim = generate(DatasetSpec(preset=wf, profiles=plist, split="train", n=opt.n_sim, seed=opt.seed),
                   workers=opt.workers, cache=opt.cache, progress=False)
    run.say("simulating the other profiles", 0.0)
    others = _others(wf, [p for p in plist if p.slug not in run.enrolled], opt.n_others, opt.seed, opt.workers,
                     opt.cache)
    classes = tuple(sim.classes)
    index = {c: i for i, c in enumerate(classes)}
    names = list(sim.feature_names)
    cols = [i for i, n in enumerate(names) if n not in GEOMETRY_FEATURES + LEVEL_FEATURES]
    y_sim = np.array([index[str(v)] for v in sim.y], dtype=np.int64)
    X_site = np.stack([s.features for s in run.site]).astype(np.float32)
    y_site = np.array([index[s.model] for s in run.site], dtype=np.int64)
    X_oth = np.nan_to_num(np.stack([s.features for s in others]), nan=0.0, posinf=1e6, neginf=-1e6) \
        if others else np.zeros((0, len(names)), dtype=np.float32)
    y_oth = np.array([index[s.model] for s in others], dtype=np.int64)
    w_site = _weights(y_sim, y_site, len(classes))
    Xs_all = np.nan_to_num(np.concatenate([sim.X, X_site]), nan=0.0, posinf=1e6, neginf=-1e6)
    jitter = float(Scene.model_fields["rotor_rate_jitter"].default)
    tip_bin = C / wf.config.carrier_hz / 2 / (wf.config.pri_s * wf.n_chirps)
    phys = physics_check(classes, {p.slug: p for p in plist}, tuple(names), jitter, tip_bin_mps=tip_bin, z=PHYS_Z,
                         max_rel_tol=PHYS_MAX_REL_TOL, min_flash_score=PHYS_MIN_FLASH_SCORE)
    return _Base(plist, sim, others, classes, names, cols, y_sim, X_site, y_site, X_oth, y_oth, Xs_all[:, cols],
                 np.concatenate([y_sim, y_site]), np.concatenate([np.ones(len(y_sim)), w_site]), phys, jitter,
                 tip_bin)


@dataclass(frozen=True)
class _Folds:
    """The cross-validation over the site recordings: `n` folds, each recording's fold and its
    out-of-fold probabilities, the folds' mean probabilities of the other profiles' returns, and
    the temperature fitted on both."""

    n: int
    fold_of: np.ndarray
    p_oof: np.ndarray
    p_oth: np.ndarray
    beta: float


def _cross_validate(run: _Run, base: _Base) -> _Folds:
    """K-fold cross-validation over the site recordings, the base set always in training."""
    from signatures.train import classifiers as clf

    n_folds = min(CV_FOLDS, min(run.det_counts.values()))
    p_oth = np.zeros((len(base.others), base.n_cls))
    n_s, cols, done = base.n_s, base.cols, [0]

    def fit_fold(train_idx: np.ndarray) -> Any:
        rows = np.concatenate([np.arange(n_s), n_s + train_idx])
        model = _fit_rf(base.X_all[rows], base.y_all[rows], base.w_all[rows], run.opt.seed, run.opt.workers)
        if len(base.others):  # the fold's forest never saw them: its mean over the folds is out of sample
            p_oth[:, model.classes_.astype(np.int64)] += model.predict_proba(base.X_oth[:, cols]) / n_folds
        done[0] += 1
        run.say("cross-validating", done[0] / (n_folds + 2))
        return model

    def proba(model: Any, idx: np.ndarray) -> np.ndarray:
        p = np.zeros((len(idx), base.n_cls))
        p[:, model.classes_.astype(np.int64)] = model.predict_proba(base.X_site[idx][:, cols])
        return p

    run.say("cross-validating", 0.0)
    p_oof, fold_of = _oof(fit_fold, proba, base.y_site, n_folds, run.opt.seed)
    beta = clf.bounded_temperature(np.concatenate([p_oof, p_oth]), np.concatenate([base.y_site, base.y_oth]))
    return _Folds(n_folds, fold_of, p_oof, p_oth, beta)


@dataclass(frozen=True)
class _OpenSetVerdicts:
    """The calibrated cross-validated predictions and open-set verdicts of the site recordings
    and of the other profiles' returns, with the bands they were verified with (`fold_bands`: each
    fold's, from the other folds' recordings; `all_bands`: from every recording)."""

    p_cal: np.ndarray
    pred: np.ndarray
    unk: np.ndarray
    p_oth_cal: np.ndarray
    pred_oth: np.ndarray
    unk_oth: np.ndarray
    fold_bands: dict[int, dict[str, Any]]
    all_bands: dict[str, Any] | None
    phys: PhysicsCheck  # with the site's rate bands where measured


def _open_set(run: _Run, base: _Base, folds: _Folds) -> _OpenSetVerdicts:
    """Calibrate the out-of-fold probabilities and apply the open set (out of fold, with the site's
    bands where they are re-estimated)."""
    from signatures.classify.ensemble import calibrate

    p_cal = calibrate(folds.p_oof, folds.beta)
    pred = p_cal.argmax(axis=1)
    max_tip = run.wf.config.unambiguous_velocity_mps
    fold_bands: dict[int, dict[str, Any]] = {}
    if run.physics_bands:  # out of fold: each recording verified with the bands of the other folds' recordings
        fold_bands = {k: site_bands([s for s, f in zip(run.site, folds.fold_of) if f != k], run.profiles, max_tip)
                      for k in range(folds.n)}
    all_bands = site_bands(run.site, run.profiles, max_tip) if run.physics_bands else None
    phys = base.phys
    if all_bands:  # the open set's rate test takes the site's measured rates too
        phys = phys.with_rate_bands(base.classes, {m: b["rate"] for m, b in all_bands.items()})
    unk = _oof_unknown(phys, base.classes, base.X_site, pred, folds.fold_of, fold_bands)
    others = len(base.others)
    p_oth_cal = calibrate(folds.p_oth, folds.beta) if others else folds.p_oth
    pred_oth = p_oth_cal.argmax(axis=1)
    unk_oth = phys.verdict(base.X_oth.astype(np.float64), pred_oth)[0] if others else np.zeros(0, dtype=bool)
    return _OpenSetVerdicts(p_cal, pred, unk, p_oth_cal, pred_oth, unk_oth, fold_bands, all_bands, phys)


@dataclass(frozen=True)
class _Scores:
    """The cross-validated verification scores the card reports (calibrated where applied):
    genuine LLRs, impostor LLRs by (claimed, true) pair, dwell scores, and the calibration choice."""

    genuine: list[float]
    impostor: dict[tuple[str, str], list[float]]
    dwell_scores: dict[tuple[str, str], list[DwellScore]]
    uncal_genuine: list[float]
    cal_genuine: list[float]
    calibration: Calibration
    choice: dict[str, dict[str, Any]]
    claimable: list[str]

    @property
    def applied(self) -> bool:
        return bool(self.calibration.applied)


def _scores(run: _Run, base: _Base, folds: _Folds, vs: _OpenSetVerdicts) -> _Scores:
    """Verify every recording against its own and every other model (out of fold), fit the score
    calibration, and choose whether it applies."""
    max_tip = run.wf.config.unambiguous_velocity_mps
    claimable = [*run.enrolled, *sorted({s.model for s in base.others})]
    rows: list[tuple[int, str, str, Any]] = []
    oth_rows: list[tuple[int, str, str, Any]] = []
    claims = _verification(run.site, vs.p_cal, ~vs.unk, base.classes, run.profiles, claimable, max_tip,
                           lambda i: vs.fold_bands.get(int(folds.fold_of[i])), rows)
    claims += _verification(base.others, vs.p_oth_cal, ~vs.unk_oth, base.classes, run.profiles, run.enrolled,
                            max_tip, lambda i: vs.all_bands, oth_rows)
    genuine, impostor, dwell_scores = _scored(claims)
    calibration, cal_genuine, cal_impostor, cal_dwells = _calibrated(rows, folds.fold_of, folds.n, oth_rows)
    sprt, seed, enrolled = run.opt.sprt, run.opt.seed, run.enrolled
    choice = {"uncalibrated": separation(genuine, impostor, dwell_scores, enrolled, sprt, seed),
              "calibrated": separation(cal_genuine, cal_impostor, cal_dwells, enrolled, sprt, seed)}
    asked = run.opt.score_calibration
    use_cal = calibration_pays(choice) if asked is None else asked
    if use_cal:  # the card's threshold, pairwise and track figures are then the calibrated scores'
        return _Scores(cal_genuine, cal_impostor, cal_dwells, genuine, cal_genuine,
                       replace(calibration, applied=use_cal), choice, claimable)
    return _Scores(genuine, impostor, dwell_scores, genuine, cal_genuine, replace(calibration, applied=use_cal),
                   choice, claimable)


def _write_bundle(run: _Run, base: _Base, folds: _Folds, vs: _OpenSetVerdicts, scores: _Scores, dest: Path,
                  t0: float) -> dict[str, Any]:
    """Fit the bundle on every site sample, write it beside `dest` and rename it into place
    (after reading it back). Returns its card."""
    from signatures.train import classifiers as clf
    from signatures.classify.inference import Classifier
    from signatures.classify.modelcard import write_card
    from signatures.classify.openset import fit_openset
    from signatures.train.training import OPENSET_MODE, OPENSET_QUANTILE, _waveform_card

    opt, n_cls = run.opt, base.n_cls
    rf = _fit_rf(base.X_all, base.y_all, base.w_all, opt.seed, opt.workers)
    knn = clf.make_knn().fit(base.X_all, base.y_all)
    uav = np.isin(base.sim.y, [p.slug for p in base.plist])
    state_head = clf.fit_state_head(base.sim.X[uav], base.sim.moving[uav], opt.seed)
    dest.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".enrol-{opt.name}-", dir=dest.parent))
    try:
        np.savez(tmp / "knn.npz", **clf.knn_arrays(knn, base.X_all, base.y_all, n_cls))
        np.savez(tmp / "rf.npz", **clf.forest_arrays(rf, n_cls))
        np.savez(tmp / "rf_state.npz", **clf.forest_arrays(state_head, 2))
        openset = fit_openset(base.sim.X, base.y_sim, n_cls, base.X_site, base.y_site, vs.pred, OPENSET_QUANTILE,
                              class_cols=np.array(base.cols, dtype=np.int64), physics=vs.phys, mode=OPENSET_MODE)
        np.savez(tmp / "openset.npz", **openset.arrays())
        np.savez(tmp / "site.npz", **site_arrays(run.samples))
        files = ["knn.npz", "rf.npz", "rf_state.npz", "openset.npz", "site.npz"]
        card = _card(run, base, folds, vs, files)
        card["enrolment"] = _enrolment_card(run, base, folds, vs, scores)
        if not run.wf.shipped:
            card["waveform"] = _waveform_card(run.wf, base.plist)
        card["enrolment"]["seconds"] = round(time.perf_counter() - t0, 2)
        write_card(tmp, card)
        Classifier(tmp)  # reads back and verifies what was written before it goes live
        try:
            os.rename(tmp, dest)  # atomic on one file system; refuses a destination that appeared meanwhile
        except OSError as exc:
            raise EnrolError(f"{dest}: could not move the bundle into place ({exc.strerror})") from None
    finally:
        if tmp.exists():
            shutil.rmtree(tmp)
    return card


def _card(run: _Run, base: _Base, folds: _Folds, vs: _OpenSetVerdicts, files: list[str]) -> dict[str, Any]:
    """The bundle's card but its enrolment section: what any bundle's card says."""
    from signatures.classify.inference import MEMBERS
    from signatures.classify.modelcard import library_versions
    from signatures.train.training import OPENSET_MODE, PHYS_MAX_REL_TOL, PHYS_MIN_FLASH_SCORE, PHYS_Z, _physics_card

    wf, n_s, n_site, names = run.wf, base.n_s, len(run.site), base.names
    return {
        "preset": wf.name,
        "radar": {**wf.config.to_dict(exclude=("range_offset_m",)), "n_chirps": wf.n_chirps,
                  "n_samples": wf.n_samples},
        "classes": list(base.classes), "feature_names": names, "class_features": [names[i] for i in base.cols],
        "profiles": [p.to_dict(json=True) for p in base.plist],
        "training": {"seed": run.opt.seed, "n_train": n_s + n_site, "n_val": 0, "base_simulated": n_s,
                     "command": "authn models enrol RECORDINGS (the card's enrolment.sources)"},
        "models": {"knn": "StandardScaler + KNeighborsClassifier(k=5) on base + site returns (unweighted)",
                   "rf": f"RandomForestClassifier(100 trees, min_samples_leaf=2) on {n_s} simulated + "
                         f"{n_site} site returns, site weight share {SITE_SHARE}",
                   "state_head": "RandomForestClassifier(50 trees) on the simulated UAV returns"},
        "ensemble": {"members": list(MEMBERS), "voting": "the forest alone (site enrolment)",
                     "weights": [0.0, 1.0, 0.0], "temperature_beta": round(folds.beta, 9)},
        "open_set": {"mode": OPENSET_MODE, "physics": {"z": PHYS_Z, "max_rel_tol": PHYS_MAX_REL_TOL,
                                                       "min_flash_score": PHYS_MIN_FLASH_SCORE,
                                                       "rotor_rate_jitter": base.jitter,
                                                       "tip_bin_mps": round(base.tip_bin, 6),
                                                       **_physics_card(vs.phys)}},
        "cnn": None, "cascade": {"threshold": 0.0},
        "libraries": library_versions(), "files": files,
        "metrics": {"validation": {"ensemble": {
            "accuracy": round(float(np.mean(vs.pred == base.y_site)), 6),
            "note": "cross-validated on the site recordings"}}},
    }


def _enrolment_card(run: _Run, base: _Base, folds: _Folds, vs: _OpenSetVerdicts, scores: _Scores) -> dict[str, Any]:
    """The card's enrolment section: method, counts, cross-validated confusion, threshold,
    calibration, pairwise errors, the signatures asked for, sources."""
    opt, enrolled, sprt = run.opt, run.enrolled, run.opt.sprt
    labels = [*base.classes, "unknown"]
    cm = np.zeros((len(enrolled), len(labels)), dtype=np.int64)
    for yi, pi, ui in zip(base.y_site, vs.pred, vs.unk):
        cm[enrolled.index(base.classes[yi]), len(base.classes) if ui else pi] += 1
    used_cols = [j for j, lab in enumerate(labels) if cm[:, j].any() or lab in enrolled]
    index = base.index
    n_oth = {m: int(np.sum(base.y_oth == index[m])) for m in scores.claimable[len(enrolled):]}
    called = {(b, a): int(np.sum((base.y_oth == index[b]) & (vs.pred_oth == index[a]) & ~vs.unk_oth))
              for a in enrolled for b in n_oth}  # simulated returns of b the system called a
    pairs = pair_cards(enrolled, run.det_counts, n_oth, cm, called, index, scores.impostor, scores.dwell_scores,
                       sprt, opt.seed)
    confusable = [p["models"] for p in pairs if single_confusable(p)]
    confusable_tracks = [p["models"] for p in pairs if track_confusable(p)] if sprt is not None else None
    return {
        "format": ENROL_FORMAT, "name": opt.name,
        "created": datetime.now(timezone.utc).replace(microsecond=0).isoformat(), "previous": opt.previous,
        "method": _method_card(run, base, folds, scores),
        "counts": {m: sum(s.model == m for s in run.samples) for m in enrolled}, "detected": run.det_counts,
        "not_detected": len(run.samples) - len(run.site),
        "confusion": {"rows": enrolled, "cols": [labels[j] for j in used_cols],
                      "matrix": cm[:, used_cols].tolist(), "cross_validated": True},
        "open_set_false_rejection": round(float(vs.unk.mean()), 6),
        "threshold": _threshold_card(scores),
        "bands": vs.all_bands,
        "calibration": _calibration_card(run, scores),
        "pairwise": pairs, "confusable_error": CONFUSABLE_ERROR,
        "others": {"simulated": n_oth, "method": f"{opt.n_others} returns per profile not enrolled, simulated in "
                   "this waveform (test split of the training scenes; never trained on), each verified "
                   "against every enrolled model, the enrolled recordings against it (out of fold)"},
        "carriers_hz": {f"{f:.6g}": n for f, n in sorted((opt.carriers or {}).items())},
        "signatures": signatures_needed(enrolled, confusable, confusable_tracks),
        "min_separable_claims": MIN_SEPARABLE_CLAIMS, "confusable_pairs": confusable,
        "confusable_pairs_tracks": confusable_tracks,
        "tracks": _tracks_card(run, scores),
        "sources": [{"file": s.name, "sha256": s.sha256, "model": s.model} for s in run.samples],
        "source_names": list(opt.sources),
        "seconds": None}


def _method_card(run: _Run, base: _Base, folds: _Folds, scores: _Scores) -> dict[str, Any]:
    """How the enrolment was made, in words, for the card."""
    return {"base": f"{base.n_s} simulated returns of the waveform (seed {run.opt.seed})",
            "classifier": f"random forest on base + site returns, site weight share {SITE_SHARE}",
            "temperature": "out-of-fold log-loss, inverse temperature bounded to 0.25..8",
            "open_set": "physical consistency with the predicted profile (as trained)",
            "physics_bands": ("rate, rotor and blade bands per enrolled model from the site recordings, "
                              f"today's bands the prior ({BAND_PRIOR_WEIGHT} pseudo-recordings)"
                              if run.physics_bands else "today's fixed bands"),
            "score_calibration": ("logistic regression on the out-of-fold verification terms "
                                  "(card `calibration`)" if scores.applied else "none (fitted and "
                                  "reported in `calibration`, not applied)"),
            "cv_folds": folds.n}


def _threshold_card(scores: _Scores) -> dict[str, Any]:
    """The applied threshold (the default policy's: radar-claim-inconsistent, LLR < 0 rejects), the
    one at the false-accept target, and the genuine acceptance at each."""
    applied = 0.0
    t_fa = threshold_at(scores.impostor, FALSE_ACCEPT_TARGET)
    g = np.asarray(scores.genuine)
    return {"applied": applied, "at_false_accept_target": t_fa, "false_accept_target": FALSE_ACCEPT_TARGET,
            "genuine_accept_at_applied": round(float(np.mean(g >= applied)), 6) if len(g) else None,
            "genuine_accept_at_target": (round(float(np.mean(g >= t_fa)), 6)
                                         if len(g) and t_fa is not None else None),
            "note": "LLR in nats; the default policy rejects below 0 (radar-claim-inconsistent)"}


def _calibration_card(run: _Run, scores: _Scores) -> dict[str, Any]:
    """The score calibration fitted, the choice between calibrated and uncalibrated scores, and
    what a genuine dwell is worth under each."""
    return {**scores.calibration.to_json(), "choice": {
        **scores.choice, "by": "auto" if run.opt.score_calibration is None else "asked",
        "rule": f"applied unasked when cross-validated genuine acceptance gains >= {CALIBRATION_GAIN} "
                "and the worst pair's false accepts do not rise (above the confusable line)"},
        "evidence_per_genuine_dwell": {
        "uncalibrated": mean_or_none(scores.uncal_genuine), "calibrated": mean_or_none(scores.cal_genuine),
        "note": "mean cross-validated LLR of genuine claims, nats: with calibrated scores what a "
                "genuine dwell is worth (its expected LLR); a track of `tracks.dwells` needs the "
                "accept bound times (1 + (n - 1) rho) / n per dwell"}}


def _tracks_card(run: _Run, scores: _Scores) -> dict[str, Any] | None:
    """Track-level genuine acceptance per enrolled model by the check's sequential test (None
    without one)."""
    sprt, seed = run.opt.sprt, run.opt.seed
    if sprt is None:
        return None
    return {
        "dwells": TRACK_DWELLS, "draws_per_direction": TRACK_DRAWS, "sprt": sprt.to_json(),
        "genuine_accept": {m: rate_or_none(track_rates(scores.dwell_scores.get((m, m), []), sprt.walk, seed=seed)[0])
                           for m in run.enrolled},
        "method": "tracks drawn without replacement from one model's cross-validated dwell scores (the "
                  "enrolment recordings are single dwells of different flights: a track of independent "
                  "dwells, pooled over the folds so that it reaches its full length), decided by the "
                  "check's own sequential test (authn.sprt.Sprt.walk); inconclusive counts as not accepted",
        "note": "a pair with tracks shorter than `dwells` keeps its single-dwell verdict for track checks"}


def default_name(wf: Preset, now: datetime | None = None) -> str:
    """`site-<waveform name>-<UTC time>`."""
    now = now or datetime.now(timezone.utc)
    return f"site-{wf.name.lower()}-{now.strftime('%Y%m%dt%H%M%S')}"
