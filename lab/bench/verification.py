"""Verification: the error rates of thresholding the check's verification score (ROC, DET,
equal error rate).

The score is the one the Cedar policy thresholds: the log-likelihood ratio of "the claimed
airframe" against "some other airframe" that `authn.check` computes for every detected target
with `signatures.classify.verify` and reports as `radar.verification.llr`. `verification_score` reads it
back from a check's radar evidence; a claim the check could not verify scores `UNVERIFIED`.
`rotor_evidence` says whether the score had the rotors' physics in it.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

#: The score of a claim with no verification (radar skipped, nothing detected, nothing to verify
#: with): below any computed score, as the policy rejects such claims.
UNVERIFIED = -100.0


def verification_score(radar: dict[str, Any] | None) -> float:
    """The check's verification LLR (nats; > 0 favours the claim), or `UNVERIFIED`."""
    verification = (radar or {}).get("verification") or {}
    terms = verification.get("terms") or {}
    return float(verification["llr"]) if terms else UNVERIFIED


def rotor_evidence(radar: dict[str, Any] | None) -> bool:
    """Whether the check saw the rotors: its physics term ran (a blade-flash rate with a flash
    score of at least `signatures.classify.verify.MIN_FLASH_SCORE`). Without it a claim rests on the
    classifier alone, so the world reports split "no rotor modulation seen" (the signal or the
    flash detector) from "seen and misjudged" (the verification)."""
    verification = (radar or {}).get("verification") or {}
    return "physics" in (verification.get("terms") or {})


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
            ax.plot(probit(far), probit(frr), linestyle=style, color=colour,
                    label=f"{label} (EER {eer(genuine, impostor):.1%})")
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
