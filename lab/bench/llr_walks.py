"""The one decision rule drawn: the sequential test's LLR against dwells for a pair radar separates and
a pair it cannot (docs/policies.md, docs/tracks.md).

Tracks of back-to-back `paper` dwells in the randomised world (the training simulator, each scene's
nuisances drawn once), every shipped model registered: a genuine Phantom 4 and an M300 flying a Phantom 4
claim (separable), a genuine M300 and an M600 flying an M300 claim (confusable). Each dwell is checked by
the real `Checker`; its increments per alternative (`Evidence.increments`) are walked as `authn check
--track` walks them (`Sprt.track_llr`), without stopping at a bound, so the curves show where the test
would have stopped.

    python -m lab.bench.llr_walks --tracks 6 --dwells 16 --snr 10 --out docs/figures/llr-vs-dwells.png
"""

from __future__ import annotations

import argparse
import tempfile
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

#: (flown, claimed, panel): the separable pair first.
WALKS = (("phantom4", "phantom4", "separable"), ("m300", "phantom4", "separable"),
         ("m300", "m300", "confusable"), ("m600", "m300", "confusable"))


def walks(tracks: int, dwells: int, snr: float, seed: int = 3) -> dict[tuple[str, str], list[list[float]]]:
    """(flown, claimed) -> per track, the track LLR after each dwell (nats)."""
    from dataclasses import replace

    from authn.check import Checker
    from authn.sprt import Sprt
    from lab.bench.decisions import CLAIM_SCENES, bench_serial, register_identities
    from lab.bench.track import track_recordings
    from signatures.profiles import shipped_profiles
    from signatures.radar import get_preset
    from signatures.sim.sampling import randomised, sample_scene

    sprt, pre = Sprt(), get_preset("paper")
    out: dict[tuple[str, str], list[list[float]]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        db = f"sqlite:///{Path(tmp) / 'walks.sqlite3'}"
        register_identities(db)
        checker = Checker(db)
        for w_idx, (flies, claims, _) in enumerate(WALKS):
            rng = np.random.default_rng([seed, w_idx, int(snr * 10) + 1000])
            for _ in range(tracks):
                scene = sample_scene(rng, shipped_profiles()[flies], replace(CLAIM_SCENES, snr_db=(snr, snr)))
                base = int(rng.integers(2**31 - 1000))
                scene = randomised(scene, np.random.default_rng([base, 41]))
                recs = track_recordings(scene, "paper", list(range(base, base + dwells)), bench_serial(claims),
                                        float(rng.uniform(0.0, 360.0)), datetime.now(timezone.utc),
                                        spacing_s=pre.dwell_s)
                incs, curve = [], []
                for rec in recs:
                    incs += checker.evaluate_recording(rec).evidence.increments()
                    curve.append(sprt.track_llr(incs))
                out.setdefault((flies, claims), []).append(curve)
    return out


def plot(curves: dict[tuple[str, str], list[list[float]]], path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from authn.sprt import Sprt

    s = Sprt()
    fig, axes = plt.subplots(1, 2, figsize=(10, 4), sharey=True)
    for ax, panel in zip(axes, ("separable", "confusable")):
        for (flies, claims, p), colour in zip(WALKS, ("tab:green", "tab:red", "tab:green", "tab:red")):
            if p != panel:
                continue
            label = f"{flies} claiming {claims}" + (" (genuine)" if flies == claims else " (spoof)")
            for i, c in enumerate(curves[(flies, claims)]):
                ax.plot(range(1, len(c) + 1), c, color=colour, alpha=0.6, lw=1, label=label if i == 0 else None)
        ax.axhline(s.accept_nats, color="k", ls="--", lw=0.8)
        ax.axhline(s.reject_nats, color="k", ls=":", lw=0.8)
        ax.set(title=f"{panel} pair", xlabel="dwells (26 ms each)")
        ax.legend(loc="lower left", fontsize=8)
    axes[0].set_ylabel("track LLR, least over alternatives (nats)")
    axes[0].text(1, s.accept_nats + 0.2, "accept", fontsize=8)
    axes[0].text(1, s.reject_nats - 0.6, "refute", fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    return path


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m lab.bench.llr_walks", description=__doc__.split("\n\n")[0])
    ap.add_argument("--tracks", type=int, default=6)
    ap.add_argument("--dwells", type=int, default=16)
    ap.add_argument("--snr", type=float, default=10.0)
    ap.add_argument("--out", type=Path, default=Path("docs/figures/llr-vs-dwells.png"))
    a = ap.parse_args(argv)
    curves = walks(a.tracks, a.dwells, a.snr)
    for (flies, claims), cs in curves.items():
        ends = [c[-1] for c in cs]
        print(f"{flies} claiming {claims}: LLR after {a.dwells} dwells, median {np.median(ends):+.2f} nats "
              f"(min {min(ends):+.2f}, max {max(ends):+.2f})")
    print(f"wrote {plot(curves, a.out)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
