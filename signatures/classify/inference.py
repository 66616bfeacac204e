"""Run a model bundle: numpy, plus onnxruntime only when the cascade runs the CNN (no scikit-learn, no torch).

`load_classifier(preset)` verifies the bundle's digests against its card and keeps the
result for the process (batch mode reuses it). `classifier_for(recording)` picks the bundle of
the recording's waveform: the shipped preset's, else a user bundle (`authn models train --like`,
under `models_dir()`) whose card describes the same waveform; a site bundle (`authn models enrol`)
that `active.json` in `models_dir()` names for the waveform goes ahead of both. Where no bundle has
the recording's exact carrier, the bundle of the nearest carrier within `signatures.classify.carrier`'s band
serves it, its Doppler-frequency features rescaled to the bundle's carrier (`predict(carrier_hz=)`).
Every model is an estimator with scikit-learn's `predict_proba` contract: the kNN, the forests and the
SVM are plain arrays evaluated in numpy (`signatures.classify.members`), combined by `signatures.classify.ensemble`'s
soft vote and temperature, the same code training weighs and calibrates them with; the CNN is an ONNX
file, opened on first use. `Classifier.predict` turns one feature vector (and optionally the RD patch)
into a `Prediction`: calibrated soft vote of kNN + RF + SVM, the CNN only when the ensemble is unsure
(cascade), then open-set rejection (physical consistency with the predicted profile, see `signatures.classify.openset`).
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from signatures.classify.calibration import calibration_of
from signatures.classify.ensemble import MEMBERS, SoftVote, Temperature
from signatures.errors import SignaturesError
from signatures.dsp.feature_vector import FEATURE_NAMES
from signatures.classify.members import OnnxCnn, load_member
from signatures.classify.modelcard import CARD_NAME, read_card
from signatures.classify.openset import OpenSet
from signatures.profiles import NON_UAV_CLASSES, UNKNOWN
from signatures.radar import (PRESETS, SERVES, TRAINABLE_DOMAINS, WAVEFORM_FIELDS, WAVEFORM_REL_TOL, Preset,
                              RadarConfig, get_preset, parse_waveform, recording_waveform, shipped_preset)

__all__ = ["ACTIVE_FORMAT", "ACTIVE_NAME", "MEMBERS", "Classifier", "NoModelError", "Prediction", "active_bundle",
           "active_map", "bundle_dir", "card_waveform", "classifier_for", "find_bundle", "load_classifier",
           "match_preset", "mismatch_head", "models_dir", "nearest_bundle", "set_active", "user_bundles",
           "waveform_differences"]

#: The file in `models_dir()` naming each waveform's active site bundle (waveform key -> folder name).
ACTIVE_NAME = "active.json"
ACTIVE_FORMAT = "uav-radar-authn/active-bundles/1"
_LOADED: dict[str, "Classifier"] = {}
_FOUND: dict[str, "Classifier"] = {}  # "models_dir:waveform key" -> the user bundle `classifier_for` picked


class NoModelError(SignaturesError):
    """No model bundle fits the recording's waveform."""


@dataclass(frozen=True)
class Prediction:
    """What the radar says about one return."""

    label: str  # profile slug, "bird", "none" or "unknown"
    confidence: float  # calibrated probability of the best known class
    known: bool  # False when open-set rejection turned the label into "unknown"
    probabilities: dict[str, float]
    operational_state: str | None  # "hovering" / "moving" for multirotors, else None
    used_cnn: bool
    nearest: str = ""  # best known class even when the label is "unknown"


class Classifier:
    """A verified model bundle ready for inference."""

    def __init__(self, folder: Path) -> None:
        self.folder = Path(folder)
        self.card, self.card_digest = read_card(self.folder)
        try:
            self._read(self.card)
        except KeyError as exc:
            raise SignaturesError(f"{self.folder}: the model bundle lacks {exc} (a layout this version does "
                                  "not read: rebuild it with `authn models train`)") from None

    def _read(self, c: dict[str, Any]) -> None:
        """Everything inference needs from the card and `openset.npz` (current bundle layout only)."""
        self.preset: str = c["preset"]
        self.waveform = card_waveform(c)
        self.classes: tuple[str, ...] = tuple(c["classes"])
        self.n_features = len(c["feature_names"])
        names = list(c["feature_names"])
        self.feature_names: tuple[str, ...] = tuple(names)
        self._cols = np.array([names.index(n) for n in c["class_features"]])
        #: a bundle trained on an earlier, shorter vector reads its features from today's by name
        #: (versions only append features; docs/features.md)
        self._by_name = (np.array([FEATURE_NAMES.index(n) for n in names])
                         if names != list(FEATURE_NAMES) and set(names) <= set(FEATURE_NAMES) else None)
        self._files = set(c["files"])
        self._loaded: dict[str, Any] = {}  # model files open on first use (a CLI check needs few)
        self._vote: Temperature | None = None
        self.has_cnn = "cnn.onnx" in self._files
        with np.load(self.folder / "openset.npz", allow_pickle=False) as z:
            self.openset = OpenSet.from_arrays({k: z[k] for k in z.files})
        self.beta = float(c["ensemble"]["temperature_beta"])
        self.weights = [float(w) for w in c["ensemble"]["weights"]]
        if len(self.weights) != len(MEMBERS):
            raise SignaturesError(f"{self.folder}: the card gives {len(self.weights)} ensemble weights, "
                                  f"one per member {MEMBERS} expected")
        self._check_members()
        self.cascade_threshold = 0.0
        self._cnn_mean, self._cnn_std = 0.0, 1.0
        if self.has_cnn:
            self.cascade_threshold = float(c["cascade"]["threshold"])
            self._cnn_mean = float(c["cnn"]["input_mean"])
            self._cnn_std = float(c["cnn"]["input_std"])
        self._uav = np.array([k not in NON_UAV_CLASSES for k in self.classes])
        enrolment = c.get("enrolment")
        #: a site bundle (`authn models enrol`): its radar-confusable pairs of enrolled models
        self.site = isinstance(enrolment, dict)
        self.confusable_pairs: tuple[tuple[str, str], ...] = tuple(
            (str(a), str(b)) for a, b in (enrolment or {}).get("confusable_pairs", []))
        #: the same over tracks (the card's track-level pairwise errors); a card without them: the single-dwell pairs
        track_pairs = (enrolment or {}).get("confusable_pairs_tracks")
        self.confusable_track_pairs: tuple[tuple[str, str], ...] = self.confusable_pairs if track_pairs is None \
            else tuple((str(a), str(b)) for a, b in track_pairs)
        #: per enrolled model, the physics bands the site's recordings gave (`signatures.classify.verify.bands_from`)
        self.physics_bands: dict[str, Any] | None = (enrolment or {}).get("bands")
        #: the site's score calibration where its card applies one (`signatures.classify.calibration`)
        self.score_calibration = calibration_of(self)
        #: a shipped card's measured separation of each pair of shipped profiles (`lab.bench.single_dwell`):
        #: (claimed, alternative) -> (genuine nats per dwell, radar cannot separate them within a track)
        self.separation: dict[tuple[str, str], tuple[float, bool]] = {
            (str(p["claimed"]), str(p["against"])): (float(p["genuine_nats_per_dwell"]), bool(p["confusable"]))
            for p in (c.get("separation") or {}).get("pairs", [])}

    def confusable_with(self, model: str, tracks: bool = False) -> tuple[str, ...]:
        """The models this bundle cannot tell `model` apart from: a site bundle's enrolled models
        whose cross-validated pairwise error is above the threshold (of single dwells, or of tracks
        when `tracks`); a shipped bundle's profiles that no track of its measured separation
        decides (one dwell never decides at the default error rates: the same pairs); () else."""
        if self.site:
            pairs = self.confusable_track_pairs if tracks else self.confusable_pairs
        else:
            pairs = tuple(pair for pair, (_, confusable) in self.separation.items() if confusable)
        return tuple(sorted({b if a == model else a for a, b in pairs if model in (a, b)}))

    def separation_of(self, model: str) -> dict[str, float]:
        """The card's measured mean per-dwell increment of a genuine `model` claim against each
        alternative ({}: not measured)."""
        return {b: nats for (a, b), (nats, _) in self.separation.items() if a == model}

    def _check_members(self) -> None:
        """Every member the vote weighs is a numpy array file (`signatures.classify.members`); an SVM exported
        as ONNX (an older layout) is refused, not run through another implementation."""
        legacy = sorted(f"{m}.onnx" for m in MEMBERS if f"{m}.onnx" in self._files)
        if legacy:
            raise SignaturesError(f"{self.folder}: {', '.join(legacy)} is a model format this version does not "
                                  "read; rebuild the bundle with `authn models train`")
        missing = [m for m, w in zip(MEMBERS, self.weights) if w and f"{m}.npz" not in self._files]
        if missing or not any(self.weights):
            raise SignaturesError(f"{self.folder}: the ensemble weighs {', '.join(missing) or 'no member'} "
                                  "and the bundle does not ship it; rebuild it with `authn models train`")

    def _model(self, name: str) -> Any:
        """A member, the state head or the CNN (`signatures.classify.members`), opened once."""
        if name not in self._loaded:
            if name == "cnn":
                self._loaded[name] = OnnxCnn(self.folder / "cnn.onnx", self._cnn_mean, self._cnn_std,
                                             len(self.classes))
            elif f"{name}.npz" in self._files:
                self._loaded[name] = load_member(self.folder / f"{name}.npz")
            else:
                raise SignaturesError(f"{self.folder}: this bundle ships no {name} model")
        return self._loaded[name]

    def _ensemble(self) -> Temperature:
        """The calibrated soft vote of the members the card weighs (each opened on first use)."""
        if self._vote is None:
            members = [self._model(m) if w else None for m, w in zip(MEMBERS, self.weights)]
            self._vote = Temperature(SoftVote(members, self.weights), self.beta)
        return self._vote

    # --- vectorised building blocks (evaluation uses these) --------------------------
    def _x(self, X: np.ndarray) -> np.ndarray:
        X = np.asarray(X, dtype=np.float32)
        X = X.reshape(1, -1) if X.ndim == 1 else X
        if X.shape[1] != self.n_features:
            if self._by_name is None or X.shape[1] != len(FEATURE_NAMES):
                raise SignaturesError(f"feature vector has {X.shape[1]} values, the model expects {self.n_features}")
            X = X[:, self._by_name]
        return np.nan_to_num(X, nan=0.0, posinf=1e6, neginf=-1e6)

    def member_proba(self, name: str, X: np.ndarray) -> np.ndarray:
        """Probabilities of one member model ('knn', 'rf', 'svm'), columns in `classes` order."""
        return self._model(name).predict_proba(self._x(X)[:, self._cols])

    def ensemble_proba(self, X: np.ndarray) -> np.ndarray:
        """Temperature-calibrated soft vote of the members (`signatures.classify.ensemble`)."""
        return self._ensemble().predict_proba(self._x(X)[:, self._cols])

    def cnn_proba(self, rd: np.ndarray) -> np.ndarray:
        if not self.has_cnn:
            raise SignaturesError("this model bundle has no CNN (train with --cnn)")
        return self._model("cnn").predict_proba(rd)

    def cascade_proba(self, X: np.ndarray, rd: np.ndarray | Callable[[], np.ndarray] | None
                      ) -> tuple[np.ndarray, np.ndarray]:
        """Ensemble, averaged with the CNN where the ensemble's top probability < threshold.
        `rd`: the patches, or a callable giving them, called only if some row needs the CNN."""
        p = self.ensemble_proba(X)
        used = np.zeros(len(p), dtype=bool)
        if self.has_cnn and rd is not None and self.cascade_threshold > 0:
            used = p.max(axis=1) < self.cascade_threshold
            if used.any():
                rd = np.asarray(rd() if callable(rd) else rd)
                rd = rd.reshape(len(p), *rd.shape[-2:])
                p[used] = 0.5 * (p[used] + self.cnn_proba(rd[used]))
        return p, used

    def moving_proba(self, X: np.ndarray) -> np.ndarray:
        """P(moving) from the operational-state head."""
        return self._model("rf_state").predict_proba(self._x(X))[:, 1]

    def unknown_mask(self, X: np.ndarray, pred: np.ndarray, mode: str | None = None) -> np.ndarray:
        """Open-set rejection of full feature vectors given their predicted class indices."""
        return self.openset.unknown(self._x(X), pred, mode)

    # --- returns -------------------------------------------------------------------
    def on_carrier(self, features: np.ndarray, carrier_hz: float | np.ndarray | None) -> np.ndarray:
        """Feature rows recorded at `carrier_hz` (one per row, or one for all; None: the bundle's)
        as this bundle's carrier would have measured them (`signatures.classify.carrier.normalise`: the
        Doppler-frequency features x lambda_rec / lambda_bundle). Lookup only hands a bundle
        recordings within its carrier band; this does not check that."""
        X = self._x(features)
        if carrier_hz is None:
            return X
        from signatures.classify.carrier import normalise

        wf = self.waveform
        return normalise(X, self.feature_names, wf.config, wf.n_samples, carrier_hz)

    def predict(self, features: np.ndarray,
                rd_patch: np.ndarray | Callable[[], np.ndarray] | None = None,
                carrier_hz: float | None = None) -> Prediction:
        """Classify one return from its feature vector (and RD patch for the cascade; a callable
        is only called when the cascade runs the CNN), recorded at `carrier_hz` (None: the bundle's)."""
        return self.predict_many(self._x(features), rd_patch, carrier_hz)[0]

    def predict_many(self, features: np.ndarray,
                     rd_patches: np.ndarray | Callable[[], np.ndarray] | None = None,
                     carrier_hz: float | np.ndarray | None = None) -> list[Prediction]:
        """Classify B returns at once (B x features; the patches B x PATCH_SHAPE, or a callable
        giving them, called only when the cascade runs the CNN for some row): every member and
        the open set run once over the batch, so a batch costs little more than one return.
        `carrier_hz` (one per row or one for all; None: the bundle's): the carriers the returns
        were recorded at, within the bundle's band; their features are put on the bundle's
        carrier first (`on_carrier`). The RD patch is not rescaled (docs/waveform.md
        "Carrier band": within the band it moves by under half of one of its 32 Doppler bands)."""
        X = self.on_carrier(features, carrier_hz)
        if len(X) > 1:  # a batch: BLAS on one thread (signatures.dsp.threads: same values, no waiting threads)
            from signatures.dsp.threads import one_blas_thread

            with one_blas_thread():
                p, used, k, known, labels, uav, moving = self._decide(X, rd_patches)
        else:
            p, used, k, known, labels, uav, moving = self._decide(X, rd_patches)
        out = []
        for i, label in enumerate(labels):
            ki = int(k[i])
            state = ("moving" if moving[i] else "hovering") if uav[i] else None
            out.append(Prediction(label=label, confidence=float(p[i, ki]), known=bool(known[i]),
                                  probabilities={c: float(v) for c, v in zip(self.classes, p[i])},
                                  operational_state=state, used_cnn=bool(used[i]), nearest=self.classes[ki]))
        return out

    def _decide(self, X: np.ndarray, rd_patches: np.ndarray | Callable[[], np.ndarray] | None):
        """`predict_many`'s arrays: probabilities, CNN use, best class, known, labels, UAV, moving."""
        p, used = self.cascade_proba(X, rd_patches)
        k = np.argmax(p, axis=1)
        known = ~self.openset.unknown(X, k)
        labels = [self.classes[ki] if kn else UNKNOWN for ki, kn in zip(k.tolist(), known.tolist())]
        uav = [label not in NON_UAV_CLASSES for label in labels]
        moving = self.moving_proba(X) >= 0.5 if any(uav) else np.zeros(len(X), bool)
        return p, used, k, known, labels, uav, moving


def card_waveform(card: dict[str, Any]) -> Preset:
    """The waveform a bundle serves: its card's `waveform.radar_config`, else the shipped preset
    its `preset` names (shipped bundles and bundles trained with `--preset`)."""
    if "waveform" in card:
        return parse_waveform(card["waveform"]["radar_config"], "model card waveform.radar_config")
    return get_preset(card["preset"])


def bundle_dir(preset: str) -> Path:
    """Folder of the shipped bundle of a preset (inside the installed package)."""
    return Path(__file__).resolve().parents[1] / "models" / preset


def models_dir() -> Path:
    """Where user bundles live: `$AUTHN_MODELS_DIR`, else `models/` in the user data folder."""
    from core.settings import current

    env = current().models_dir
    if env:
        return Path(env)
    import platformdirs

    return Path(platformdirs.user_data_dir("authn")) / "models"


def user_bundles() -> list[tuple[Path, dict[str, Any] | None]]:
    """Bundle folders under `models_dir()` with their cards as read (not verified: loading
    verifies), None for a card that is not JSON."""
    root = models_dir()
    if not root.is_dir():
        return []
    out: list[tuple[Path, dict[str, Any] | None]] = []
    for folder in sorted(p for p in root.iterdir() if (p / CARD_NAME).is_file()):
        try:
            card = json.loads((folder / CARD_NAME).read_text())
        except (OSError, ValueError):
            card = None
        out.append((folder, card if isinstance(card, dict) else None))
    return out


def active_map() -> dict[str, str]:
    """Waveform key -> the name of its active site bundle, from `models_dir()/active.json` ({}
    without one). A file that is not what `set_active` writes stops the check (fail closed:
    silently falling back to another bundle would change every decision)."""
    path = models_dir() / ACTIVE_NAME
    try:
        doc = json.loads(path.read_text())
    except FileNotFoundError:
        return {}
    except (OSError, ValueError) as exc:
        raise SignaturesError(f"{path}: unreadable ({exc}); `authn models use NAME|shipped` rewrites it") from None
    active = doc.get("active") if isinstance(doc, dict) and doc.get("format") == ACTIVE_FORMAT else None
    if not isinstance(active, dict) or not all(isinstance(k, str) and isinstance(v, str) and _plain(v)
                                               for k, v in active.items()):
        raise SignaturesError(f"{path}: not an {ACTIVE_FORMAT} file; `authn models use NAME|shipped` rewrites it")
    return dict(active)


def _plain(name: str) -> bool:
    return bool(name) and "/" not in name and "\\" not in name and not name.startswith(".")


def set_active(key: str, name: str | None) -> None:
    """Make `name` the active site bundle of waveform `key` (None: back to the shipped or trained
    bundle), or with key "*" and None, every waveform. Written to a temporary file and renamed:
    a reader sees the old map or the new one."""
    import tempfile

    active = active_map()
    if key == "*" and name is None:
        active = {}
    elif name is None:
        active.pop(key, None)
    else:
        active[key] = name
    root = models_dir()
    root.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=".active-", dir=root)
    try:
        with os.fdopen(fd, "w") as f:
            json.dump({"format": ACTIVE_FORMAT, "active": dict(sorted(active.items()))}, f, indent=1)
            f.write("\n")
        os.replace(tmp, root / ACTIVE_NAME)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def _keys(wf: Preset) -> tuple[str, ...]:
    """The waveform keys whose bundles serve `wf`: its own, and an IF bundle's for a range file."""
    from signatures.radar import waveform_key

    keys = [wf.key]
    for domain, served in SERVES.items():
        if domain != wf.domain and wf.domain in served:
            keys.append(waveform_key(wf.config, wf.n_chirps, wf.n_samples, domain))
    return tuple(keys)


def active_bundle(wf: Preset) -> Path | None:
    """The folder of the active site bundle serving `wf`, or None: the one active for the
    waveform itself, else the active one of the nearest carrier within the band
    (`signatures.classify.carrier`). An active name whose folder is gone is an error, not a fallback."""
    active = active_map()
    for key in _keys(wf):
        if key in active:
            return _active_folder(active[key])
    band: list[tuple[float, str]] = []
    for name in sorted(set(active.values())):
        folder = _active_folder(name)
        try:
            card = json.loads((folder / CARD_NAME).read_text())
        except (OSError, ValueError):
            continue  # loading it, had it been picked, names the problem
        ratio = _ratio(card, wf, site=True)
        if ratio is not None:
            band.append((abs(math.log(ratio)), name))
    return models_dir() / min(band)[1] if band else None


def _active_folder(name: str) -> Path:
    folder = models_dir() / name
    if not (folder / CARD_NAME).is_file():
        raise NoModelError(f"the active site bundle {name!r} is missing from {models_dir()}; "
                           "`authn models use shipped` or enrol again")
    return folder


def _ratio(card: dict[str, Any] | None, wf: Preset, site: bool = False) -> float | None:
    """f_file / f_bundle when the card's bundle serves `wf` within the carrier band (None: it
    does not, or the card is a site bundle's and `site` is False, or of another layout)."""
    from signatures.classify.carrier import carrier_ratio

    try:
        if card is None or ("enrolment" in card) != site:
            return None
        return carrier_ratio(card_waveform(card), wf)
    except (SignaturesError, KeyError, TypeError):
        return None  # a card of another layout serves nothing here; loading it names the problem


def _serves(card: dict[str, Any] | None, wf: Preset) -> bool:
    try:
        return card is not None and "enrolment" not in card \
            and card_waveform(card).matches(wf.config, wf.n_chirps, wf.n_samples, wf.domain)
    except (SignaturesError, KeyError, TypeError):
        return False  # a card of another layout serves nothing here; loading it names the problem


def find_bundle(wf: Preset, source: str = "FILE") -> Path:
    """The bundle folder for a waveform: the shipped preset's, else the user bundle whose card
    describes it (the one named after the waveform first); else, where no bundle has the exact
    carrier, the shipped or user bundle of the nearest carrier within the carrier band
    (`signatures.classify.carrier.CARRIER_BAND_REL`; ties by name); else NoModelError naming the fix."""
    from signatures.classify.carrier import carrier_ratio

    if wf.shipped:
        return bundle_dir(wf.name)
    users = user_bundles()
    for folder, card in sorted(users, key=lambda fc: (fc[0].name != wf.name, fc[0].name)):
        if _serves(card, wf):
            return folder
    band: list[tuple[float, str, Path]] = []
    for name, pre in PRESETS.items():
        ratio = carrier_ratio(pre, wf)
        if ratio is not None:
            band.append((abs(math.log(ratio)), name, bundle_dir(name)))
    for folder, card in users:
        ratio = _ratio(card, wf)
        if ratio is not None:
            band.append((abs(math.log(ratio)), folder.name, folder))
    if band:
        return min(band)[2]
    found = nearest_bundle(wf)
    head = mismatch_head(found[0], found[1]) if found is not None else ""
    if wf.domain not in TRAINABLE_DOMAINS:
        raise NoModelError(f"{head}no classifier for this waveform ({wf.describe()}): training for domain "
                           f"{wf.domain} is not supported yet{nearest_hint(wf)}")
    raise NoModelError(f"{head}no classifier for this waveform ({wf.describe()}): build one with "
                       f"`authn models train --like {source}`{nearest_hint(wf)}")


#: The order in which differing parameters are named: the clock first (a CW radar's PRI, bandwidth
#: and ramp all follow its sample rate), then the carrier, then the sweep.
_TELLING = ("sample_rate_hz", "pri_s", "carrier_hz", "bandwidth_hz", "ramp_s")


def waveform_differences(bundle: Preset, wf: Preset) -> list[tuple[str, Any, Any]]:
    """The parameters in which a bundle's waveform differs from a file's beyond what serving
    tolerates, as (name, bundle value, file value): cube size, domain, then in `_TELLING` order
    the carrier outside the carrier band (`signatures.classify.carrier`) and each other of WAVEFORM_FIELDS
    beyond `Preset.matches`'s relative tolerance (WAVEFORM_REL_TOL). Empty exactly when the bundle
    serves the file."""
    from signatures.classify.carrier import CARRIER_BAND_REL

    out: list[tuple[str, Any, Any]] = []
    for name in ("n_chirps", "n_samples"):
        if getattr(bundle, name) != getattr(wf, name):
            out.append((name, getattr(bundle, name), getattr(wf, name)))
    if wf.domain not in SERVES[bundle.domain]:
        out.append(("domain", bundle.domain, wf.domain))
    for f in sorted(WAVEFORM_FIELDS, key=_TELLING.index):
        a, b = getattr(bundle.config, f), getattr(wf.config, f)
        tol = CARRIER_BAND_REL * (1.0 + 1e-9) if f == "carrier_hz" else WAVEFORM_REL_TOL
        if (abs(b / a - 1.0) > tol) if f == "carrier_hz" else not math.isclose(a, b, rel_tol=tol):
            out.append((f, a, b))
    return out


def _distance(diffs: list[tuple[str, Any, Any]]) -> tuple[int, float]:
    """How far apart: the number of differing parameters, then the summed |log ratio| of the numbers."""
    spread = sum(abs(math.log(a / b)) for _, a, b in diffs
                 if isinstance(a, (int, float)) and isinstance(b, (int, float)) and a > 0 and b > 0)
    return len(diffs), spread


def nearest_bundle(wf: Preset) -> tuple[str, list[tuple[str, Any, Any]]] | None:
    """The bundle (shipped or user, by name) whose waveform differs from `wf` in the fewest
    parameters (then by the least), with those differences; None when there is no bundle."""
    cands: list[tuple[str, Preset]] = [(name, p) for name, p in PRESETS.items()]
    for folder, card in user_bundles():
        try:
            if card is not None:
                cands.append((folder.name, card_waveform(card)))
        except (SignaturesError, KeyError, TypeError):
            continue
    scored = [(_distance(d), name, d) for name, p in cands for d in [waveform_differences(p, wf)]]
    if not scored:
        return None
    _, name, diffs = min(scored, key=lambda t: (t[0], t[1]))
    return name, diffs


def _value(name: str, v: Any) -> str:
    return repr(v) if isinstance(v, float) else str(v)


#: A waveform parameter in words and its unit, for the first words of a mismatch.
_WORDS = {"n_chirps": ("pulses per dwell", ""), "n_samples": ("samples per pulse", ""), "domain": ("domain", ""),
          "carrier_hz": ("carrier", " Hz"), "bandwidth_hz": ("bandwidth", " Hz"), "ramp_s": ("ramp", " s"),
          "pri_s": ("PRI", " s"), "sample_rate_hz": ("sample rate", " Hz")}


def mismatch_head(bundle: str, diffs: list[tuple[str, Any, Any]]) -> str:
    """'sample rate 5000.0 Hz here, 5100.0 Hz in bundle X: ', the first parameter in which the
    bundle `bundle` differs from the file (`waveform_differences`), so that a mismatch message
    starts with what differs; '' where nothing does."""
    if not diffs:
        return ""
    field, theirs, ours = diffs[0]
    words, unit = _WORDS.get(field, (field, ""))
    return f"{words} {_value(field, ours)}{unit} here, {_value(field, theirs)}{unit} in bundle {bundle}: "


def nearest_hint(wf: Preset) -> str:
    """'; nearest bundle paper differs in pri_s: 4.5e-05 there, 4.403e-05 here (tolerance 0.001
    relative); exact values: `authn models list --json`', or '' when there is no bundle."""
    found = nearest_bundle(wf)
    if found is None or not found[1]:
        return ""
    from signatures.classify.carrier import CARRIER_BAND_REL

    name, diffs = found
    parts = []
    for field, theirs, ours in diffs:
        tol = f", tolerance {WAVEFORM_REL_TOL:g} relative" if field in WAVEFORM_FIELDS else ""
        if field == "carrier_hz":
            tol = f", carrier band +-{CARRIER_BAND_REL:.1%}"
        parts.append(f"{field} {_value(field, theirs)} there, {_value(field, ours)} here{tol}")
    return (f"; nearest bundle {name} differs in {'; '.join(parts)} (exact values: `authn models list --json`)")


def load_classifier(preset: str | None = None, path: str | Path | None = None) -> Classifier:
    """The verified classifier of a shipped preset or a user bundle (by name), or of the bundle at
    `path` (cached)."""
    if path is None:
        if preset is None:
            raise SignaturesError("give a preset or a model bundle path")
        if preset in PRESETS:
            folder = bundle_dir(preset)
        elif preset and "/" not in preset and not preset.startswith(".") \
                and (models_dir() / preset / CARD_NAME).is_file():
            folder = models_dir() / preset
        else:
            raise NoModelError(f"no model named {preset!r} (shipped: {', '.join(PRESETS)}; "
                               "user bundles: `authn models list`)")
    else:
        folder = Path(path)
    key = str(folder.resolve())
    if key not in _LOADED:
        if not (folder / "card.json").is_file():
            raise NoModelError(f"{folder}: no model bundle here (card.json missing); "
                               "build one with `authn models train`")
        _LOADED[key] = Classifier(folder)
    return _LOADED[key]


def match_preset(config: RadarConfig, n_chirps: int, n_samples: int) -> str:
    """The shipped preset whose waveform the recording used (range offset aside), or NoModelError."""
    pre = shipped_preset(config, n_chirps, n_samples)
    if pre is None:
        raise NoModelError(f"no classifier for this waveform ({n_chirps}x{n_samples} at "
                           f"{config.carrier_hz / 1e9:g} GHz, PRI {config.pri_s * 1e6:.3g} us) among the "
                           f"shipped presets {', '.join(PRESETS)}")
    return pre.name


def classifier_for(recording: Any, model: str | Path | None = None, source: str = "FILE") -> Classifier:
    """The classifier for a Recording's waveform (`find_bundle`; kept per waveform for the
    process), or the bundle at `model`, which must serve that waveform (its carrier within the
    band). `source` names the file in the hint of NoModelError. The bundle's carrier may differ
    from the recording's: pass the recording's `carrier_hz` to `Classifier.predict`."""
    from signatures.classify.carrier import CARRIER_BAND_REL, carrier_ratio

    wf = recording_waveform(recording)
    if model is not None:
        clf = load_classifier(path=model)
        if carrier_ratio(clf.waveform, wf) is None:
            head = mismatch_head(Path(model).name, waveform_differences(clf.waveform, wf))
            raise NoModelError(f"{head}{model}: this bundle is for {clf.waveform.describe()} (carrier band "
                               f"+-{CARRIER_BAND_REL:.1%}), the file's waveform is {wf.describe()}")
        return clf
    site = active_bundle(wf)
    if site is not None:
        return load_classifier(path=site)
    if wf.shipped:
        return load_classifier(wf.name)
    key = f"{models_dir()}:{wf.key}"
    if key not in _FOUND:
        _FOUND[key] = load_classifier(path=find_bundle(wf, source))
    return _FOUND[key]
