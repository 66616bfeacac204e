"""Open-set rejection: a return that does not fit its predicted class is `unknown`.

Two tests, both fitted at training time; a bundle ships, as plain arrays (`openset.npz`), the
fitted values and hyper-parameters of the tests its mode applies, and nothing else:

1. **Physical consistency** (the main test, UAV predictions only). The feature vector
   carries physical estimates with uncertainties; the predicted profile (from the
   bundle's card: profiles are data) says what they must be:

   * blade-flash rate: |f_est - F| <= max(z * sqrt(s_est^2 + (j F)^2), 0.08 F), where F is the
     profile's blade-flash rate (`UavProfile.blade_flash_rate_hz`), s_est the estimator's
     stated std (`flash_rate_std_hz`, scatter of the matched flash intervals), j the
     simulator's per-rotor rate jitter (a single rotor's rate is off by up to 3 j), and the
     0.08 F floor the estimator's demonstrated accuracy on known airframes;
   * `wide` (tips not aliased): the line-of-sight tip speed cannot exceed the profile's
     2 pi f_rot L (the projection only shrinks it): tip_est <= T (1 + 3 j) + max(z s_tip + 1 bin, 0.03 T).
     This test does not use the rate estimate at all.

   **Aliased preset: period slips.** When the blade tips alias (the `paper` preset) the
   flash estimator's typical error is a whole-period slip (it reports 2x, 1/2x or 3x the
   rate with a confident std); there a rate within tolerance of 1/2, 2 or 3 times F also
   counts as consistent. An unknown airframe whose flash rate sits exactly at such a
   multiple of a known one passes this test in `paper` (not in `wide`).

   **Unreliable estimates abstain.** When the flash-rate estimate is absent (rate 0,
   fewer than 2 matched flash pairs) or its tolerance would exceed `max_rel_tol` of F (then
   it could not tell apart profiles differing by 2 x max_rel_tol, the design's 20 %), the
   rate test says nothing and the return is judged by the other tests. The tip test only
   runs when the tips are not aliased. `bird` and `none` are never checked here: they are
   classes, not airframes.

   Rotor count is *not* tested: the distinct-flash-phase count is too noisy (docs/classifiers.md, "Open set").

2. **Distance to the class manifold** (optional, all classes): mean Euclidean distance, in
   standardised feature space, to the k nearest training returns of the predicted class;
   threshold = `quantile` of that score over the class's correctly classified validation
   returns. Which tests the bundle applies (`mode`: "physics", "distance" or "both") is
   chosen at training time and recorded in the card with the validation numbers behind it.

Both estimators follow scikit-learn's convention: hyper-parameters are constructor arguments
(their defaults apply only when fitting), fitted values end in `_`; a loaded bundle supplies
every one of them from its file, so editing a default here never changes a shipped model.

numpy only: this runs on the inference path.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from signatures.errors import SignaturesError

__all__ = ["ALIASED_RATE_SLIPS", "MODES", "PHYS_FEATURES", "OpenSet", "PhysicsCheck", "fit_openset",
           "knn_distance", "physics_check"]

MODES = ("physics", "distance", "both")
#: Flash-rate multiples accepted as estimator slips when the blade tips alias (paper preset).
ALIASED_RATE_SLIPS = (0.5, 2.0, 3.0)
#: Estimator fields the physical test reads (names in the model's full feature vector).
PHYS_FEATURES = ("flash_rate_hz", "flash_rate_std_hz", "flash_score", "tip_speed_mps", "tip_speed_std_mps",
                 "tip_aliased")


def knn_distance(Z: np.ndarray, ref: np.ndarray, k: int) -> np.ndarray:
    """Mean distance of each row of Z to its k nearest rows of ref."""
    d2 = (np.sum(Z * Z, axis=1)[:, None] - 2.0 * Z @ ref.T + np.sum(ref * ref, axis=1)[None, :])
    d = np.sqrt(np.maximum(d2, 0.0))
    kk = min(k, ref.shape[0])
    part = np.partition(d, kk - 1, axis=1)[:, :kk]
    return part.mean(axis=1)


def _require(z: Mapping[str, np.ndarray], name: str) -> np.ndarray:
    if name not in z:
        raise KeyError(f"openset.npz array {name!r}")
    return z[name]


@dataclass
class PhysicsCheck:
    """Physical consistency of a return with its predicted profile (see the module docstring).

    Hyper-parameters first; `fit` sets the per-class expectations from the bundle's profiles.
    """

    #: std of the simulator's per-rotor rate offset (a single rotor is off by up to 3 jitter)
    jitter: float = 0.005
    #: tolerance in sigmas of (estimator std (+) rotor-rate jitter)
    z: float = 4.0
    #: the rate test abstains when its tolerance exceeds this share of F: it could then not
    #: separate profiles 2 x this apart (the design's 20 %)
    max_rel_tol: float = 0.10
    #: below this flash score the rate estimate is noise: the rate test abstains
    min_flash_score: float = 1.0
    #: The rate test is never sharper than the estimator's demonstrated accuracy on known
    #: airframes (5 % for most returns, docs/features.md "Estimator accuracy"): 8 % still separates
    #: profiles 20 % apart, the open-set design point.
    min_rel_tol: float = 0.08
    #: Tip-speed upper bound slack: the spectral-edge estimate is ~2 % high on moving airframes
    #: with a stated std far below that; 3 % still flags tips 20 % too fast.
    min_rel_tip_tol: float = 0.03
    #: one Doppler bin in m/s (the tip edge is quantised to it)
    tip_bin_mps: float = 0.0
    #: flash-rate multiples accepted as whole-period slips when the tips alias
    rate_slips: tuple[float, ...] = ALIASED_RATE_SLIPS
    # fitted: expected values per class index (0 = no check for that class: bird / none)
    flash_hz_: np.ndarray | None = field(default=None, repr=False)
    tip_mps_: np.ndarray | None = field(default=None, repr=False)
    #: indices of PHYS_FEATURES in the full feature vector (-1: absent)
    cols_: np.ndarray | None = field(default=None, repr=False)
    #: per class index, the flown rate over the nominal a site measured ([lo, hi]; a site bundle's
    #: enrolled models, `with_rate_bands`): a rate inside it is consistent too. None: the nominal alone
    rate_band_: np.ndarray | None = field(default=None, repr=False)

    #: scalar hyper-parameters, stored by name in `openset.npz`
    SCALARS = ("jitter", "z", "max_rel_tol", "min_flash_score", "min_rel_tol", "min_rel_tip_tol", "tip_bin_mps")

    def fit(self, classes: Sequence[str], profiles: Mapping[str, object],
            feature_names: Sequence[str]) -> "PhysicsCheck":
        """Expected blade-flash rate and tip speed of each class (from its profile; 0 for classes
        that are not airframes) and where the estimator fields sit in the feature vector."""
        self.flash_hz_ = np.array([getattr(profiles.get(c), "blade_flash_rate_hz", 0.0) for c in classes],
                                  dtype=np.float64)
        self.tip_mps_ = np.array([getattr(profiles.get(c), "tip_speed_mps", 0.0) for c in classes],
                                 dtype=np.float64)
        names = list(feature_names)
        self.cols_ = np.array([names.index(n) if n in names else -1 for n in PHYS_FEATURES], dtype=np.int64)
        return self

    def _col(self, X: np.ndarray, name: str) -> np.ndarray | None:
        i = int(self.cols_[PHYS_FEATURES.index(name)])
        return None if i < 0 else np.asarray(X[:, i], dtype=np.float64)

    def rate_tolerance(self, X: np.ndarray, pred: np.ndarray) -> np.ndarray:
        F = self.flash_hz_[pred]
        s = self._col(X, "flash_rate_std_hz")
        s = np.zeros(len(X)) if s is None else s
        return np.maximum(self.z * np.sqrt(s * s + (self.jitter * F) ** 2), self.min_rel_tol * F)

    def verdict(self, X: np.ndarray, pred: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(inconsistent, checked): rate or tip speed contradicts the predicted profile / a test ran."""
        pred = np.asarray(pred, dtype=int)
        n = len(X)
        bad = np.zeros(n, dtype=bool)
        checked = np.zeros(n, dtype=bool)
        F = self.flash_hz_[pred]
        f = self._col(X, "flash_rate_hz")
        if f is not None:
            tol = self.rate_tolerance(X, pred)
            score = self._col(X, "flash_score")
            reliable = (F > 0) & (f > 0) & (tol <= self.max_rel_tol * F)
            if score is not None:
                reliable &= score >= self.min_flash_score
            checked |= reliable
            # In the aliased preset the flash estimator's typical failure is a whole-period
            # slip (2x or 1/2x, sometimes 3x the rate) with a confident std: accept those
            # harmonics there rather than call a known airframe unknown.
            alias_col = self._col(X, "tip_aliased")
            aliased = np.zeros(n, dtype=bool) if alias_col is None else alias_col >= 0.5
            miss = np.abs(f - F) > tol
            if self.rate_band_ is not None:  # a site's measured band of the class's rate
                lo, hi = self.rate_band_[pred, 0] * F, self.rate_band_[pred, 1] * F
                miss &= ~((f >= lo - tol) & (f <= hi + tol))
            for m in self.rate_slips:
                miss &= ~(aliased & (np.abs(f - m * F) <= m * tol))
            bad |= reliable & miss
        T = self.tip_mps_[pred]
        tip, alias = self._col(X, "tip_speed_mps"), self._col(X, "tip_aliased")
        if tip is not None and alias is not None:
            ts = self._col(X, "tip_speed_std_mps")
            ts = np.zeros(n) if ts is None else ts
            run = (T > 0) & (alias < 0.5) & (tip > 0)
            checked |= run
            slack = np.maximum(self.z * ts + self.tip_bin_mps, self.min_rel_tip_tol * T)
            bad |= run & (tip > T * (1 + 3 * self.jitter) + slack)
        return bad, checked

    def arrays(self) -> dict[str, np.ndarray]:
        """Everything `verdict` reads, as flat arrays: fitted values and every hyper-parameter."""
        return {"phys_flash_hz": np.asarray(self.flash_hz_, dtype=np.float64),
                "phys_tip_mps": np.asarray(self.tip_mps_, dtype=np.float64),
                "phys_cols": np.asarray(self.cols_, dtype=np.int64),
                "phys_param_names": np.array(self.SCALARS),
                "phys_param_values": np.array([float(getattr(self, n)) for n in self.SCALARS], dtype=np.float64),
                "phys_rate_slips": np.array(self.rate_slips, dtype=np.float64),
                **({} if self.rate_band_ is None
                   else {"phys_rate_band": np.asarray(self.rate_band_, dtype=np.float64)})}

    def with_rate_bands(self, classes: Sequence[str], bands: Mapping[str, Sequence[float]]) -> "PhysicsCheck":
        """A copy whose rate test also takes each named class's rate band (flown over nominal,
        [lo, hi]; a site's `signatures.train.site_bands.site_bands`) as consistent; the others' stay [1, 1]."""
        from dataclasses import replace

        band = np.ones((len(classes), 2))
        for i, c in enumerate(classes):
            if c in bands:
                band[i] = [float(bands[c][0]), float(bands[c][1])]
        return replace(self, rate_band_=band)

    @classmethod
    def from_arrays(cls, z: Mapping[str, np.ndarray]) -> "PhysicsCheck":
        """Inverse of `arrays`; every hyper-parameter must be in the file (no code default applies)."""
        names = [str(n) for n in _require(z, "phys_param_names")]
        values = [float(v) for v in _require(z, "phys_param_values")]
        if len(names) != len(values) or set(names) - set(cls.SCALARS):
            raise SignaturesError(f"openset.npz: physical-check parameters {names} are not {list(cls.SCALARS)}")
        params = dict(zip(names, values))
        for name in cls.SCALARS:
            if name not in params:
                raise KeyError(f"openset.npz physical-check parameter {name!r}")
        return cls(**params, rate_slips=tuple(float(v) for v in _require(z, "phys_rate_slips")),
                   flash_hz_=_require(z, "phys_flash_hz"), tip_mps_=_require(z, "phys_tip_mps"),
                   cols_=_require(z, "phys_cols"), rate_band_=z["phys_rate_band"] if "phys_rate_band" in z else None)


@dataclass
class OpenSet:
    """Open-set rejection: the physical check and / or the distance to the class manifold.

    Hyper-parameters first; `fit` sets the distance test's standardisation, per-class reference
    sets (standardised) and thresholds. `physics` is a PhysicsCheck already fitted to the profiles.
    """

    mode: str = "distance"  # which tests `unknown` applies: one of MODES
    k: int = 5  # neighbours averaged by the distance score
    quantile: float = 0.995  # threshold quantile of correctly classified validation scores
    class_cols: np.ndarray | None = None  # columns of the full vector the distance uses (None: all)
    physics: PhysicsCheck | None = None
    # fitted (distance test)
    mean_: np.ndarray | None = field(default=None, repr=False)
    scale_: np.ndarray | None = field(default=None, repr=False)
    refs_: list[np.ndarray] | None = field(default=None, repr=False)  # per class index
    thresholds_: np.ndarray | None = field(default=None, repr=False)  # per class index; inf = never reject

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ValueError(f"unknown open-set mode {self.mode!r}")

    def fit(self, X_train: np.ndarray, y_train: np.ndarray, n_classes: int, X_val: np.ndarray,
            y_val: np.ndarray, pred_val: np.ndarray) -> "OpenSet":
        """References from training data, thresholds from correctly classified validation returns.

        X_* are full feature vectors when `class_cols` is set (the distance then uses those columns).
        """
        Xt = X_train if self.class_cols is None else X_train[:, self.class_cols]
        self.mean_ = Xt.mean(axis=0).astype(np.float64)
        self.scale_ = Xt.std(axis=0).astype(np.float64)
        self.scale_[self.scale_ == 0] = 1.0
        Z = (Xt - self.mean_) / self.scale_
        self.refs_ = [Z[y_train == c] for c in range(n_classes)]
        self.thresholds_ = np.full(n_classes, np.inf)
        s = self.scores(X_val, pred_val)
        ok = pred_val == y_val
        for c in range(n_classes):
            m = ok & (y_val == c)
            if m.sum() >= 5:
                self.thresholds_[c] = float(np.quantile(s[m], self.quantile))
        return self

    def standardise(self, X: np.ndarray) -> np.ndarray:
        return (np.asarray(X, dtype=np.float64) - self.mean_) / self.scale_

    def _class_x(self, X: np.ndarray) -> np.ndarray:
        return X if self.class_cols is None else X[:, self.class_cols]

    def scores(self, X: np.ndarray, pred: np.ndarray) -> np.ndarray:
        """Distance of each return (full feature vector) to the training manifold of its predicted class."""
        if self.refs_ is None:
            raise SignaturesError("this open-set model has no distance test (its bundle ships "
                                  f"mode {self.mode!r} only)")
        Z = self.standardise(self._class_x(np.asarray(X)))
        pred = np.asarray(pred, dtype=int)
        out = np.empty(len(Z))
        for c in np.unique(pred):
            m = pred == c
            out[m] = knn_distance(Z[m], self.refs_[int(c)], self.k)
        return out

    def distance_unknown(self, X: np.ndarray, pred: np.ndarray) -> np.ndarray:
        """True where the return lies beyond its class's distance threshold, or has no distance (NaN:
        fail closed, `unknown`)."""
        return ~(self.scores(X, pred) <= self.thresholds_[np.asarray(pred, dtype=int)])

    def physics_unknown(self, X: np.ndarray, pred: np.ndarray) -> np.ndarray:
        if self.physics is None:
            raise SignaturesError("this open-set model has no physical check")
        return self.physics.verdict(np.asarray(X), pred)[0]

    def unknown(self, X: np.ndarray, pred: np.ndarray, mode: str | None = None) -> np.ndarray:
        """True where the return (full feature vector) does not fit its predicted class."""
        mode = mode or self.mode
        X = np.asarray(X)
        out = np.zeros(len(X), dtype=bool)
        if mode in ("physics", "both"):
            out |= self.physics_unknown(X, pred)
        if mode in ("distance", "both"):
            out |= self.distance_unknown(X, pred)
        return out

    def arrays(self, modes: Sequence[str] | None = None) -> dict[str, np.ndarray]:
        """Flat arrays for an `.npz` (no pickle): what the tests of `modes` read (default: this
        model's own mode, all that a shipped bundle needs)."""
        modes = (self.mode,) if modes is None else tuple(modes)
        out = {"mode": np.array(self.mode)}
        if any(m in ("distance", "both") for m in modes):
            out.update(mean=self.mean_, scale=self.scale_, thresholds=self.thresholds_, k=np.array(self.k))
            if self.class_cols is not None:
                out["class_cols"] = np.asarray(self.class_cols, dtype=np.int64)
            out.update({f"ref_{i}": r.astype(np.float32) for i, r in enumerate(self.refs_)})
        if any(m in ("physics", "both") for m in modes) and self.physics is not None:
            out.update(self.physics.arrays())
        return out

    @classmethod
    def from_arrays(cls, z: Mapping[str, np.ndarray]) -> "OpenSet":
        """Inverse of `arrays`: the tests present in the file (those of its mode at least)."""
        model = cls(mode=str(_require(z, "mode")))
        if "phys_flash_hz" in z or model.mode in ("physics", "both"):
            model.physics = PhysicsCheck.from_arrays(z)
        if "thresholds" in z or model.mode in ("distance", "both"):
            model.thresholds_ = _require(z, "thresholds")
            model.k = int(_require(z, "k"))
            model.mean_, model.scale_ = _require(z, "mean"), _require(z, "scale")
            model.refs_ = [_require(z, f"ref_{i}").astype(np.float64) for i in range(len(model.thresholds_))]
            model.class_cols = z["class_cols"] if "class_cols" in z else None
        return model


def physics_check(classes: tuple[str, ...], profiles: dict[str, object], feature_names: tuple[str, ...],
                  jitter: float, tip_bin_mps: float = 0.0, z: float = 4.0, max_rel_tol: float = 0.10,
                  min_flash_score: float = 1.0) -> PhysicsCheck:
    """The physical check of a bundle: expected rates / tip speeds of its profiles, by class index."""
    return PhysicsCheck(jitter=jitter, z=z, max_rel_tol=max_rel_tol, min_flash_score=min_flash_score,
                        tip_bin_mps=tip_bin_mps).fit(classes, profiles, feature_names)


def fit_openset(X_train: np.ndarray, y_train: np.ndarray, n_classes: int, X_val: np.ndarray,
                y_val: np.ndarray, pred_val: np.ndarray, quantile: float, k: int = 5,
                class_cols: np.ndarray | None = None, physics: PhysicsCheck | None = None,
                mode: str = "distance") -> OpenSet:
    """`OpenSet(...).fit(...)`: references from training data, thresholds from correctly
    classified validation returns (see `OpenSet.fit`)."""
    return OpenSet(mode=mode, k=k, quantile=quantile, class_cols=class_cols,
                   physics=physics).fit(X_train, y_train, n_classes, X_val, y_val, pred_val)
