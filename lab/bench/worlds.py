"""Identity claims checked in two worlds: the training simulator and the held-out model.

The same scenes (geometry, SNR, clutter, Remote ID, simulator seed) are rendered once by
`signatures.sim.simulate` (the world the classifiers were fitted to) and once by
`lab.heldout` (a different signal model they never saw), and each return is checked
by the real `Checker` against the bench registry (`lab.bench.decisions`). Claims:
genuine (a registered serial, its true airframe), type spoofs (a serial registered as one
shipped model, flown by another) and unseen airframes (`lab.heldout.unseen_profiles`,
never trained on) claiming a registered serial. Each return is also scored for verification
(`lab.bench.verification.verification_score`: the check's own LLR). Nothing here may be used to train or tune anything.
"""

from __future__ import annotations

import statistics
import tempfile
import time
from collections import Counter, defaultdict
from collections.abc import Callable
from dataclasses import dataclass, replace
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from lab.bench.decisions import CLAIM_SCENES, bench_serial, is_right, register_identities
from lab.bench.verification import eer, rotor_evidence, verification_score
from authn.scenario import Broadcast, remote_id_rows, simulate_flight
from signatures.profiles import UavProfile, shipped_profiles
from signatures.radar import Preset, get_preset
from signatures.recording import Recording, write_recording
from signatures.sim.sampling import sample_scene
from signatures.sim.scene import Scene

WORLDS = ("training", "heldout")
WORLD_CATEGORIES = ("genuine", "type_spoof", "unseen")
WORLD_EXPECTED = {"genuine": "accept", "type_spoof": "reject", "unseen": "reject"}
#: impostor kinds of the verification report, each against the genuine claims
IMPOSTORS = ("type_spoof", "unseen")
DEFAULT_SNRS = (0.0, 10.0)


def world_choice(world: str) -> tuple[str, ...]:
    """The worlds a `--world` value names."""
    from core.errors import BadInput

    if world == "both":
        return WORLDS
    if world not in WORLDS:
        raise BadInput(f"--world: {world!r} is not one of training, heldout, both")
    return (world,)


@dataclass(frozen=True)
class Trial:
    """One checked claim."""

    preset: str
    world: str
    snr_db: float
    category: str
    flies: str
    claims: str
    decision: str
    reasons: tuple[str, ...]
    radar_model: str | None
    score: float
    check_ms: float
    rotor_evidence: bool  # the verification's physics term ran (`verification.rotor_evidence`)

    @property
    def correct(self) -> bool:
        return is_right(WORLD_EXPECTED[self.category], self.decision)


def render_claim(world: str, scene: Scene, preset: Preset, seed: int, broadcast: Broadcast, azimuth_deg: float,
                 start_time: datetime) -> Recording:
    """The return of `scene` in `world`, carrying the drone's Remote ID."""
    if world == "training":
        return simulate_flight(scene, preset, seed, broadcast, azimuth_deg=azimuth_deg, start_time=start_time)[0]
    from lab import heldout

    rec, _ = heldout.simulate(scene, preset, seed, start_time=start_time)
    rows, times = remote_id_rows(rec, scene, broadcast, azimuth_deg, preset.dwell_s)
    return replace(rec, remote_id=rows, remote_id_time_s=times)


def _pair(cat: str, i: int, slugs: list[str], unseen: list[str]) -> tuple[str, str]:
    """(airframe flown, model claimed) of the i-th claim of a category."""
    if cat == "genuine":
        return slugs[i % len(slugs)], slugs[i % len(slugs)]
    if cat == "type_spoof":
        return slugs[i % len(slugs)], slugs[(i + 1 + (i // 3) % 2) % len(slugs)]
    return unseen[i % len(unseen)], slugs[i % len(slugs)]


def run_worlds(presets: tuple[str, ...], worlds: tuple[str, ...], n: int, seed: int,
               snrs: tuple[float, ...] = DEFAULT_SNRS, progress: Callable[[int], None] | None = None) -> list[Trial]:
    """n claims per category, SNR and preset, each checked in every world (same scene and seed)."""
    from authn.check import Checker
    from lab.heldout import unseen_profiles

    profiles: dict[str, UavProfile] = {**shipped_profiles(), **unseen_profiles()}
    slugs, unseen = list(shipped_profiles()), list(unseen_profiles())
    trials: list[Trial] = []
    with tempfile.TemporaryDirectory() as tmp:
        db = f"sqlite:///{Path(tmp) / 'worlds.sqlite3'}"
        register_identities(db)
        checker = Checker(db)
        now = datetime.now(timezone.utc)
        for p_idx, preset in enumerate(presets):
            pre = get_preset(preset)
            for s_idx, snr in enumerate(snrs):
                for c_idx, cat in enumerate(WORLD_CATEGORIES):
                    rng = np.random.default_rng([seed, p_idx, s_idx, c_idx, 13])
                    for i in range(n):
                        flies, claims = _pair(cat, i, slugs, unseen)
                        scene = sample_scene(rng, profiles[flies], replace(CLAIM_SCENES, snr_db=float(snr)))
                        az, sim_seed = float(rng.uniform(0.0, 360.0)), int(rng.integers(2**31))
                        bc = Broadcast(serial=bench_serial(claims))
                        for world in worlds:
                            rec = render_claim(world, scene, pre, sim_seed, bc, az, now)
                            path = write_recording(rec, Path(tmp) / "claim.h5")
                            t0 = time.perf_counter()
                            out = checker.evaluate(path)
                            ms = (time.perf_counter() - t0) * 1e3
                            radar = out.to_json()["radar"]
                            trials.append(Trial(preset, world, float(snr), cat, flies, claims, out.decision,
                                                tuple(out.reasons), None if out.radar is None else out.radar.model,
                                                verification_score(radar), ms, rotor_evidence(radar)))
                            if progress:
                                progress(1)
    return trials


def _group(trials: list[Trial]) -> dict[tuple[str, float, str, str], list[Trial]]:
    groups: dict[tuple[str, float, str, str], list[Trial]] = defaultdict(list)
    for t in trials:
        groups[(t.preset, t.snr_db, t.category, t.world)].append(t)
    return groups


def correct_rates(trials: list[Trial]) -> dict[tuple[str, float, str, str], float]:
    """Share of right decisions per (preset, SNR, category, world)."""
    return {k: sum(t.correct for t in g) / len(g) for k, g in _group(trials).items()}


def evidence_rates(trials: list[Trial]) -> dict[tuple[str, float, str, str], tuple[float, float | None]]:
    """Per (preset, SNR, category, world): (share of claims whose rotors were seen, share of right
    decisions among those; None where none were seen)."""
    out = {}
    for k, g in _group(trials).items():
        seen = [t for t in g if t.rotor_evidence]
        out[k] = (len(seen) / len(g), sum(t.correct for t in seen) / len(seen) if seen else None)
    return out


def equal_error_rates(trials: list[Trial],
                      rotor_evidence: bool | None = None) -> dict[tuple[str, float, str, str], float]:
    """EER of genuine against each impostor kind per (preset, SNR, impostor, world); with
    `rotor_evidence` True or False, among the claims whose rotors were (not) seen only (cells
    where either side has no such claim are left out)."""
    if rotor_evidence is not None:
        trials = [t for t in trials if t.rotor_evidence == rotor_evidence]
    groups = _group(trials)
    out = {}
    for (preset, snr, cat, world), g in groups.items():
        genuine = groups.get((preset, snr, "genuine", world))
        if cat in IMPOSTORS and genuine:
            out[(preset, snr, cat, world)] = eer([t.score for t in genuine], [t.score for t in g])
    return out


def summarise_worlds(trials: list[Trial]) -> dict[str, object]:
    """JSON view: per preset, SNR, category and world the decisions, the reasons and the
    "flown->claimed" pairs of the wrong ones, how often the rotors were seen and the right
    decisions among those, what the classifier said, and the scores; EERs, and the EERs among
    the claims whose rotors were not seen (what the classifier alone separates there)."""
    doc: dict[str, dict] = defaultdict(lambda: defaultdict(lambda: defaultdict(dict)))
    evidence = evidence_rates(trials)
    for (preset, snr, cat, world), g in _group(trials).items():
        wrong = Counter(",".join(t.reasons) for t in g if not t.correct)
        seen, right_if_seen = evidence[(preset, snr, cat, world)]
        doc[preset][f"{snr:g}"][cat][world] = {
            "n": len(g), "correct_rate": sum(t.correct for t in g) / len(g), "wrong_reasons": dict(wrong),
            "inconclusive_rate": sum(t.decision == "inconclusive" for t in g) / len(g),
            "rotor_evidence_rate": seen, "correct_rate_with_rotor_evidence": right_if_seen,
            "wrong_pairs": dict(Counter(f"{t.flies}->{t.claims}" for t in g if not t.correct)),
            "radar_models": dict(Counter(t.radar_model or "not-run" for t in g)),
            "median_check_ms": round(statistics.median(t.check_ms for t in g), 2),
            "scores": [round(t.score, 6) for t in g]}
    def keyed(eers: dict[tuple[str, float, str, str], float]) -> dict[str, float]:
        return {f"{p}/{s:g}/{c}/{w}": round(v, 4) for (p, s, c, w), v in eers.items()}

    return {"decisions": {p: {s: dict(c) for s, c in d.items()} for p, d in doc.items()},
            "eer": keyed(equal_error_rates(trials)),
            "eer_without_rotor_evidence": keyed(equal_error_rates(trials, rotor_evidence=False))}


def plot_worlds(trials: list[Trial], folder: Path) -> list[Path]:
    """`det-<preset>.png`: genuine against type spoofs and against unseen airframes, one curve per
    SNR and world (training solid, held-out dashed)."""
    from lab.bench.verification import plot_det

    groups = _group(trials)
    written = []
    colours = ["tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple"]
    for preset in dict.fromkeys(t.preset for t in trials):
        panels: dict[str, list] = {}
        snrs = sorted({t.snr_db for t in trials if t.preset == preset})
        for cat in IMPOSTORS:
            curves = []
            for s_idx, snr in enumerate(snrs):
                for world, dash in (("training", "-"), ("heldout", "--")):
                    g, imp = groups.get((preset, snr, "genuine", world)), groups.get((preset, snr, cat, world))
                    if g and imp:
                        curves.append((f"{world} {snr:g} dB", [t.score for t in g], [t.score for t in imp], dash,
                                       colours[s_idx % len(colours)]))
            panels[f"genuine vs {cat.replace('_', ' ')}"] = curves
        path = folder / f"det-{preset}.png"
        plot_det(panels, path, f"{preset}: DET of the verification score (training vs held-out world)")
        written.append(path)
    return written
