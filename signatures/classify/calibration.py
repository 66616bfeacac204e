"""Score calibration of the 1:1 verification, fitted on a site's cross-validated scores (docs/enrolment.md).

`signatures.classify.verify` adds a physics term scored against fixed bands and a classifier log-odds term
clipped at +-3 nats; both were tuned on our own simulator, and on another radar their errors are
systematic (too confident, or not confident enough). A site enrolment sees those errors: every
enrolment recording is verified out of fold against its own model (genuine) and against every
other enrolled model (type spoof). `fit` maps a dwell's raw terms

* `physics`: the physics term (nats, as `verify` computes it; 0 where it abstained),
* `physics_above_knee`: max(physics, `PHYSICS_KNEE`) (a floored physics term is strong evidence
  against; a high one may be worth less: two slopes, both >= 0),
* `classifier`: the classifier's log-odds of the claim against its prior 1/K, clipped at
  +-`CLASSIFIER_CLIP` (wider than verify's 3 nats: the site's data decides its weight) and capped
  at 0 where the open set calls the return unknown (as in verify); 0 where absent,

to a calibrated log-likelihood ratio by logistic regression of genuine against type spoof: the
two classes weighted equally (so the intercept carries no prior: the output is an LLR), L2
regularised (`L2`), the slopes constrained to >= 0 (more physical or classifier support never
lowers the score) and the intercept to <= 0: a calibration never supports a claim by itself. With
no evidence (physics and classifier both 0, or a return the open set calls unknown, whose classifier
term is capped at 0) the calibrated LLR is at most 0; a card fitted before this constraint has its
intercept clipped at 0 where it is applied. Where the physics term abstained the calibrated score keeps no physics term,
so `Verification.physics_abstained` still holds: `Sprt.increment(physics=False)` still lets it count
only against the claim.

The coefficients live in the site card (`enrolment.calibration`, JSON); `verify` applies them only
when the active bundle's card says `applied` (`authn models enrol --calibrate`). Every other
bundle verifies exactly as before. `fit` needs scipy (the enrolment path only); applying is math.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from signatures.errors import SignaturesError

__all__ = ["CALIBRATION_FORMAT", "CLASSIFIER_CLIP", "FEATURES", "L2", "PHYSICS_KNEE", "Calibration", "RawTerms",
           "calibration_of", "fit"]

CALIBRATION_FORMAT = "uav-radar-authn/score-calibration/1"
FEATURES = ("physics", "physics_above_knee", "classifier")
#: Below this physics term (nats) the first slope alone applies.
PHYSICS_KNEE = -2.0
#: The classifier's log-odds as the calibration reads them, nats.
CLASSIFIER_CLIP = 8.0
#: L2 penalty on the slopes, per unit of total sample weight (each class weighs 1 in all).
L2 = 0.01


@dataclass(frozen=True)
class RawTerms:
    """What verify computed before clipping or calibration: the physics term (None: abstained),
    the classifier's log-odds of the claim against its prior (None: the claim is not a class of
    the bundle), and the open-set verdict."""

    physics: float | None
    classifier_odds: float | None
    known: bool = True

    def vector(self) -> tuple[float, float, float]:
        """The calibration's features (`FEATURES`)."""
        p = 0.0 if self.physics is None else float(self.physics)
        c = 0.0
        if self.classifier_odds is not None:
            c = max(-CLASSIFIER_CLIP, min(CLASSIFIER_CLIP if self.known else 0.0, float(self.classifier_odds)))
        return p, (0.0 if self.physics is None else max(p, PHYSICS_KNEE)), c


@dataclass(frozen=True)
class Calibration:
    """Slopes per `FEATURES` and an intercept: calibrated LLR = coef . features + intercept."""

    coef: tuple[float, float, float]
    intercept: float
    applied: bool = True
    fitted_on: Mapping[str, int] | None = None  # {"genuine": n, "type_spoof": n}

    def terms(self, raw: RawTerms) -> dict[str, float]:
        """The calibrated terms (their sum is the LLR): `physics` only where the physics term ran,
        `classifier` only where the classifier scored the claim, `offset` where either did."""
        p, pk, c = raw.vector()
        out: dict[str, float] = {}
        if raw.physics is not None:
            out["physics"] = self.coef[0] * p + self.coef[1] * pk
        if raw.classifier_odds is not None:
            out["classifier"] = self.coef[2] * c
        if out:
            out["offset"] = min(self.intercept, 0.0)  # never support by itself (module docstring)
        return out

    def llr(self, raw: RawTerms) -> float:
        return sum(self.terms(raw).values())

    def to_json(self) -> dict[str, Any]:
        return {"format": CALIBRATION_FORMAT, "applied": self.applied, "features": list(FEATURES),
                "coef": [round(v, 9) for v in self.coef], "intercept": round(self.intercept, 9),
                "physics_knee": PHYSICS_KNEE, "classifier_clip": CLASSIFIER_CLIP, "l2": L2,
                "fitted_on": dict(self.fitted_on or {}),
                "method": "logistic regression of genuine against type-spoof claims on the enrolment's "
                          "out-of-fold verification terms, classes weighted equally (the output is an LLR), "
                          "slopes >= 0"}

    @classmethod
    def from_json(cls, doc: Mapping[str, Any] | None) -> "Calibration | None":
        """From a card's `enrolment.calibration` (None: none). A calibration of another format or
        with other features is refused, not guessed at."""
        if not doc:
            return None
        try:
            if doc["format"] != CALIBRATION_FORMAT or list(doc["features"]) != list(FEATURES) \
                    or float(doc["physics_knee"]) != PHYSICS_KNEE or float(doc["classifier_clip"]) != CLASSIFIER_CLIP:
                raise SignaturesError(f"score calibration: format {doc.get('format')!r} with features "
                                      f"{doc.get('features')!r} is not the one this version applies")
            coef = tuple(float(v) for v in doc["coef"])
            intercept = float(doc["intercept"])
        except (KeyError, TypeError, ValueError) as exc:
            raise SignaturesError(f"score calibration: unreadable ({exc})") from None
        if len(coef) != len(FEATURES) or not all(math.isfinite(v) and v >= 0.0 for v in coef) \
                or not math.isfinite(intercept):
            raise SignaturesError("score calibration: slopes must be finite and >= 0, the intercept finite")
        return cls(coef=coef, intercept=intercept, applied=bool(doc.get("applied", False)),  # type: ignore[arg-type]
                   fitted_on={str(k): int(v) for k, v in (doc.get("fitted_on") or {}).items()})


def fit(raws: Sequence[RawTerms], genuine: Sequence[bool], applied: bool = True) -> Calibration:
    """The calibration of `raws` (one per claim, out of fold) labelled genuine or not (module
    docstring). Needs both classes."""
    import numpy as np
    from scipy.optimize import minimize

    X = np.array([r.vector() for r in raws], dtype=np.float64).reshape(-1, len(FEATURES))
    y = np.asarray(genuine, dtype=bool)
    n_g, n_i = int(y.sum()), int((~y).sum())
    if n_g == 0 or n_i == 0:
        raise SignaturesError("score calibration: needs genuine and type-spoof claims")
    w = np.where(y, 0.5 / n_g, 0.5 / n_i)  # each class weighs 1/2: no prior in the intercept
    t = np.where(y, 1.0, -1.0)

    def loss(theta: np.ndarray) -> tuple[float, np.ndarray]:
        s = X @ theta[:-1] + theta[-1]
        m = -t * s
        val = float(np.sum(w * np.logaddexp(0.0, m))) + 0.5 * L2 * float(theta[:-1] @ theta[:-1])
        g = w * (-t) / (1.0 + np.exp(-m))  # d/ds of log(1 + e^m)
        grad = np.concatenate([X.T @ g + L2 * theta[:-1], [g.sum()]])
        return val, grad

    res = minimize(loss, np.zeros(len(FEATURES) + 1), jac=True, method="L-BFGS-B",
                   bounds=[(0.0, None)] * len(FEATURES) + [(None, 0.0)])
    theta = res.x
    return Calibration(coef=tuple(float(v) for v in theta[:-1]), intercept=float(theta[-1]),  # type: ignore[arg-type]
                       applied=applied, fitted_on={"genuine": n_g, "type_spoof": n_i})


def calibration_of(classifier: Any) -> Calibration | None:
    """The score calibration a bundle's card applies (None: none, or not applied); a loaded
    bundle keeps it as `Classifier.score_calibration`."""
    card = getattr(classifier, "card", None)
    enrolment = card.get("enrolment") if isinstance(card, dict) else None
    cal = Calibration.from_json(enrolment.get("calibration")) if isinstance(enrolment, dict) else None
    return cal if cal is not None and cal.applied else None
