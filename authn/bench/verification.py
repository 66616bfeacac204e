"""Verification: how consistent a radar return is with a claimed airframe, and the error rates
of thresholding that score (ROC, DET, equal error rate).

`verification_score` is the one place the score is defined; the benchmark calls it through
`SCORE`. It takes what the radar found on the return (`RadarCase`: the check's radar
evidence, the classifier's `Prediction` and the features) and the claimed `UavProfile`, and
returns a number where higher means more consistent with the claim. A physics-based score
(rotor rate, blade length and count against the claimed profile) replaces it by assigning
`SCORE` or passing `score=` to `authn.bench.worlds.run_worlds`; nothing else changes.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from signatures.profiles import UavProfile

if TYPE_CHECKING:
    from signatures.features import FeatureResult
    from signatures.inference import Prediction
    from signatures.recording import Recording


@dataclass(frozen=True)
class RadarCase:
    """What the radar found on one claimed return.

    radar: the check's radar evidence (`Outcome.radar`: model, confidence, known, range, ...);
        None when the radar did not run.
    prediction: the classifier's full output (every class's calibrated probability); None
        when no target was detected.
    features: the feature vector and its estimates (`signatures.features.FeatureResult`);
        None when the radar did not run.
    """

    radar: dict[str, Any] | None
    prediction: "Prediction | None"
    features: "FeatureResult | None"


VerificationScore = Callable[[RadarCase, UavProfile], float]


def verification_score(case: RadarCase, claimed: UavProfile) -> float:
    """The classifier's calibrated probability of the claimed class; 0 when nothing was
    detected or the open-set check called the airframe unknown."""
    pred = case.prediction
    if pred is None or not pred.known:
        return 0.0
    return float(pred.probabilities.get(claimed.slug, 0.0))


#: The score the benchmark uses.
SCORE: VerificationScore = verification_score


def radar_case(rec: "Recording", radar: dict[str, Any] | None) -> RadarCase:
    """The check's radar stage once more, keeping what the check reduces away: features gated
    at the Remote ID's expected range exactly as `authn.check` gates them, and the full
    `Prediction`."""
    if radar is None:
        return RadarCase(None, None, None)
    from authn.evidence import read_claim
    from authn.kinematics import expected_from_radar
    from signatures.features import extract
    from signatures.inference import classifier_for

    claim = read_claim(rec, None)
    gate = None
    if claim.state is not None:
        expected = expected_from_radar(claim.state, rec.site.lat_deg, rec.site.lon_deg, rec.site.alt_m,
                                       rec.start_time)
        lo, hi = rec.config.range_window_m
        gate = expected.range_m if lo <= expected.range_m < hi else None
    feats = extract(rec, expected_range_m=gate)
    if not feats.detected:
        return RadarCase(radar, None, feats)
    pred = classifier_for(rec).predict(feats.as_array(), lambda: feats.rd_patch)
    return RadarCase(radar, pred, feats)


def roc(genuine: Sequence[float], impostor: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
    """False acceptance and false rejection rates when a claim is accepted at score >= t, for
    t from -inf (accept all: FAR 1, FRR 0) through every distinct score to +inf (FAR 0, FRR 1)."""
    g = np.sort(np.asarray(genuine, dtype=np.float64))
    i = np.sort(np.asarray(impostor, dtype=np.float64))
    if g.size == 0 or i.size == 0:
        raise ValueError("need at least one genuine and one impostor score")
    t = np.concatenate([[-np.inf], np.unique(np.concatenate([g, i])), [np.inf]])
    far = 1.0 - np.searchsorted(i, t, side="left") / i.size
    frr = np.searchsorted(g, t, side="left") / g.size
    return far, frr


def eer(genuine: Sequence[float], impostor: Sequence[float]) -> float:
    """Equal error rate: where FRR = FAR on the ROC, by linear interpolation between its points."""
    far, frr = roc(genuine, impostor)
    gap = frr - far  # -1 at the first point, +1 at the last, non-decreasing
    k = int(np.argmax(gap >= 0.0))
    lam = -gap[k - 1] / (gap[k] - gap[k - 1])
    return float(far[k - 1] + lam * (far[k] - far[k - 1]))


def plot_det(panels: dict[str, list[tuple[str, Sequence[float], Sequence[float], str, str]]], path: Path,
             title: str) -> None:
    """DET curves on normal-deviate axes, one panel per impostor kind. Each curve: (label,
    genuine scores, impostor scores, line style, colour); rates of 0 or 1 sit on the edges."""
    from statistics import NormalDist

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    lo = 0.002
    probit = np.vectorize(lambda p: NormalDist().inv_cdf(float(np.clip(p, lo, 1 - lo))))
    ticks = [0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.4, 0.6, 0.8]
    fig, axes = plt.subplots(1, len(panels), figsize=(5.2 * len(panels), 5.0), squeeze=False)
    for ax, (name, curves) in zip(axes[0], panels.items()):
        for label, genuine, impostor, style, colour in curves:
            far, frr = roc(genuine, impostor)
            ax.plot(probit(far), probit(frr), linestyle=style, color=colour, label=f"{label} (EER {eer(genuine, impostor):.1%})")
        ax.plot(probit([lo, 1 - lo]), probit([lo, 1 - lo]), ":", color="grey", lw=0.8)
        ax.set_xticks(probit(ticks), [f"{100 * p:g}" for p in ticks])
        ax.set_yticks(probit(ticks), [f"{100 * p:g}" for p in ticks])
        edge = NormalDist().inv_cdf(lo / 2)  # perfect curves run along the edges, inside the frame
        ax.set_xlim(edge, probit(0.95))
        ax.set_ylim(edge, probit(0.95))
        ax.set_xlabel("false acceptance rate (%)")
        ax.set_ylabel("false rejection rate (%)")
        ax.set_title(name)
        ax.grid(True, lw=0.3)
        ax.legend(fontsize=7, loc="upper right", framealpha=0.85)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
