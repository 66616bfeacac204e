"""Numerical stress suite: the pipeline on hostile but legal inputs, and illegal ones.

Every case either gives finite features (and, for pure amplitude scaling, the same
decision as the unscaled return) or a specific bad-input error; anything else is a
crash. NaN/Inf-bearing cubes must be refused. Every case with features is also run
with float64 transforms (the 'numpy' FFT backend: complex128 FFTs) against float32 ones
(the 'scipy' backend: complex64 FFTs, what a batch job runs): the report gives the largest
relative deviation of the float32 features from it, the cases above FFT64_RTOL, and the
cases where the classifier's label differs.
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, replace
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from lab.bench.decisions import bench_serial, register_identities
from authn.scenario import Broadcast, simulate_flight
from signatures.profiles import shipped_profiles
from signatures.radar import get_preset
from signatures.recording import Recording, write_recording
from signatures.sim.scene import Scene

SERIAL = bench_serial("m300")
#: features from float32 transforms within this relative deviation (of max(|float64 value|, 1)) of
#: those from float64 transforms count as equal.
FFT64_RTOL = 2e-3


@dataclass
class StressReport:
    cases: int = 0
    crashes: list[str] = field(default_factory=list)
    nonfinite: list[str] = field(default_factory=list)
    specific_errors: list[str] = field(default_factory=list)
    scale_decision_changes: list[str] = field(default_factory=list)
    nan_inf_not_refused: list[str] = field(default_factory=list)
    fft64_max_rel: list[float] = field(default_factory=list)  # per case with features
    fft64_deviations: list[str] = field(default_factory=list)  # cases above FFT64_RTOL
    fft64_label_changes: list[str] = field(default_factory=list)

    def as_dict(self) -> dict:
        dev = np.array(self.fft64_max_rel or [0.0])
        return {"cases": self.cases, "crashes": len(self.crashes), "nonfinite_features": len(self.nonfinite),
                "scale_dependent_decisions": len(self.scale_decision_changes),
                "nan_inf_not_refused": len(self.nan_inf_not_refused),
                "specific_errors": len(self.specific_errors),
                "fft64_compared": len(self.fft64_max_rel),
                "fft64_median_max_rel_deviation": float(np.median(dev)),
                "fft64_max_rel_deviation": float(dev.max()),
                "fft64_cases_above_rtol": len(self.fft64_deviations),
                "fft64_label_changes": len(self.fft64_label_changes),
                "details": {"crashes": self.crashes, "nonfinite": self.nonfinite,
                            "scale_decision_changes": self.scale_decision_changes,
                            "specific_errors": self.specific_errors,
                            "fft64_deviations": self.fft64_deviations,
                            "fft64_label_changes": self.fft64_label_changes}}


def _base(preset: str, seed: int, snr: float = 15.0, **scene_kw) -> Recording:
    kw = {"range_m": 300.0, "radial_speed_mps": 3.0, **scene_kw}
    scene = Scene(profile=shipped_profiles()["m300"], snr_db=snr, **kw)
    rec, _ = simulate_flight(scene, get_preset(preset), seed, Broadcast(serial=SERIAL),
                             start_time=datetime.now(timezone.utc))
    return rec


def _adc(iq: np.ndarray, dtype: str) -> np.ndarray:
    """What an ADC of that type would have delivered (rounded/quantised), back as complex."""
    if dtype == "int16":
        scale = 32000.0 / max(float(np.max(np.abs(iq.view(np.float32)))), 1e-30)
        q = np.round(iq.view(np.float32) * scale).astype(np.int16)
        return (q.astype(np.float32) / scale).view(np.complex64)
    if dtype == "float16":
        return iq.view(np.float32).astype(np.float16).astype(np.float32).view(np.complex64)
    return iq.astype(np.complex128 if dtype == "float64" else np.complex64)


def _clip(iq: np.ndarray, frac: float) -> np.ndarray:
    parts = iq.view(np.float32)
    level = frac * float(np.max(np.abs(parts)))
    return np.clip(parts, -level, level).view(np.complex64)


def cases(preset: str, quick: bool) -> Iterator[tuple[str, str, Callable[[], Recording]]]:
    """(group, name, recording factory)."""
    pre = get_preset(preset)
    base = _base(preset, 1)
    exps = [0, *(e for e in (range(-30, 31, 15) if quick else range(-30, 31, 5)) if e)]  # reference first
    for e in exps:
        yield "scale", f"x1e{e}", lambda e=e: replace(base, iq=(base.iq.astype(np.complex128) * 10.0**e)
                                                       .astype(np.complex64) if abs(e) < 37 else base.iq)
    for dt in ("float16", "float32", "float64", "int16"):
        yield "adc", dt, lambda dt=dt: replace(base, iq=_adc(base.iq, dt))
    yield "degenerate", "all-zero", lambda: replace(base, iq=np.zeros_like(base.iq))
    yield "degenerate", "constant", lambda: replace(base, iq=np.full_like(base.iq, 3 - 2j))
    yield "degenerate", "one huge spike", lambda: replace(
        base, iq=np.where(np.arange(base.iq.size).reshape(base.iq.shape) == 777, 1e30, 0).astype(np.complex64))
    for frac in (0.5, 0.05):
        yield "adc", f"clipped at {frac:.0%}", lambda f=frac: replace(base, iq=_clip(base.iq, f))
    yield "shape", "one chirp", lambda: replace(base, iq=base.iq[:1].copy())
    yield "shape", "one range bin", lambda: replace(base, iq=base.iq[:, :1].copy())
    primes = {"paper": (599, 79), "wide": (8191, 61)}.get(preset, (pre.n_chirps - 1, pre.n_samples - 1))
    odd = (pre.n_chirps - 5, pre.n_samples - 5)
    yield "shape", f"prime sizes {primes[0]}x{primes[1]}", lambda: replace(
        base, iq=base.iq[: primes[0], : primes[1]].copy())
    yield "shape", f"odd sizes {odd[0]}x{odd[1]}", lambda: replace(base, iq=base.iq[: odd[0], : odd[1]].copy())
    for snr in ((-40, 0, 80) if quick else (-40, -20, -10, 0, 20, 40, 60, 80)):
        yield "snr", f"{snr:+d} dB", lambda s=snr: _base(preset, 2, snr=float(s))
    vu = pre.config.unambiguous_velocity_mps
    geometry = {"range 1 m": dict(range_m=1.0, radial_speed_mps=0.0),
                "window edge": dict(range_m=1199.0, radial_speed_mps=0.0),
                "hover": dict(radial_speed_mps=0.0),
                "at v_unamb": dict(radial_speed_mps=vu * 0.999),
                "beyond v_unamb": dict(radial_speed_mps=min(vu * 1.7, 200.0))}
    for name, kw in geometry.items():
        yield "geometry", name, lambda kw=kw: _base(preset, 3, **kw)


def run(presets: tuple[str, ...] = ("paper",), quick: bool = False, db_url: str | None = None) -> StressReport:
    """Run every case through features and a full decision; NaN/Inf files through the file reader."""
    from authn.check import Checker
    from core.errors import BadInput
    from signatures.features import extract

    report = StressReport()
    bad = BadInput
    with tempfile.TemporaryDirectory() as tmp:
        db = db_url or f"sqlite:///{Path(tmp) / 'stress.sqlite3'}"
        register_identities(db)
        checker = Checker(db)
        for preset in presets:
            reference: str | None = None
            for group, name, make in cases(preset, quick):
                label = f"{preset}/{group}/{name}"
                report.cases += 1
                try:
                    rec = make()
                    fr = extract(rec)
                    if not np.all(np.isfinite(fr.as_array())):
                        report.nonfinite.append(label)
                    _against_fft64(report, label, rec)
                    decision = checker.evaluate_recording(rec).decision
                except bad as exc:
                    report.specific_errors.append(f"{label}: {exc}")
                    continue
                except Exception as exc:  # noqa: BLE001 - a crash is what this suite counts
                    report.crashes.append(f"{label}: {type(exc).__name__}: {exc}")
                    continue
                if group == "scale":
                    reference = reference or decision
                    if decision != reference:
                        report.scale_decision_changes.append(f"{label}: {decision} != {reference}")
            _nan_inf_refused(report, preset, checker, Path(tmp))
    return report


def _against_fft64(report: StressReport, label: str, rec: Recording) -> None:
    """Deviation of the features from float32 transforms from those from float64 transforms;
    label change if a model fits."""
    from dataclasses import astuple

    from signatures.features import FEATURE_NAMES, extract
    from signatures.classify.inference import NoModelError, classifier_for

    single = extract(rec, fft_backend="scipy")
    double = extract(rec, fft_backend="numpy")
    a = np.array(astuple(single.features), dtype=np.float64)
    b = np.array(astuple(double.features), dtype=np.float64)
    rel = np.abs(a - b) / np.maximum(np.abs(b), 1.0)
    report.fft64_max_rel.append(float(rel.max()))
    if rel.max() > FFT64_RTOL:
        worst = [f"{FEATURE_NAMES[i]} {a[i]:.6g} vs {b[i]:.6g}" for i in np.argsort(rel)[::-1][:3]
                 if rel[i] > FFT64_RTOL]
        report.fft64_deviations.append(f"{label}: " + "; ".join(worst))
    try:
        clf = classifier_for(rec)
    except NoModelError:
        return
    one, two = clf.predict(single.as_array()).label, clf.predict(double.as_array()).label
    if one != two:
        report.fft64_label_changes.append(f"{label}: {one} (float32) vs {two} (float64)")


def _nan_inf_refused(report: StressReport, preset: str, checker, tmp: Path) -> None:
    from signatures.errors import RecordingError

    base = _base(preset, 4)
    for name, value in (("NaN", np.nan), ("+Inf", np.inf), ("-Inf", -np.inf)):
        report.cases += 1
        iq = base.iq.copy()
        iq[5, 7] = value
        path = tmp / f"bad-{name}.h5"
        try:
            import h5py

            write_recording(base, path)
            with h5py.File(path, "a") as f:
                f["iq"][...] = iq
            checker.evaluate(path)
        except RecordingError:
            continue
        except Exception as exc:  # noqa: BLE001
            report.crashes.append(f"{preset}/nan-inf/{name}: {type(exc).__name__}: {exc}")
            continue
        report.nan_inf_not_refused.append(f"{preset}/nan-inf/{name}")


def is_clean(report: StressReport) -> bool:
    return not (report.crashes or report.nonfinite or report.scale_decision_changes
                or report.nan_inf_not_refused)
