"""FMCW radar configuration, waveforms (the two shipped presets and any other, docs/waveform.md
"Your radar's waveform") and what they imply.

Everything here is closed-form physics: range resolution c/2B, beat frequency
2*S*R/c, unambiguous velocity lambda*PRF/4 (complex slow-time sampling), Doppler
bin lambda/(2*N*PRI). No signal processing.
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from core.checked import Checked, Invalid, choice, integer, number
from core.parsing import JsonTooDeep, loads_json
from signatures.profiles import UavProfile

C = 299_792_458.0  # speed of light, m/s


@dataclass(frozen=True, kw_only=True)
class RadarConfig(Checked):
    """Waveform of one recorded dwell: the radar attributes of docs/format.md (checked on
    construction: `core.checked`)."""

    carrier_hz: float = number(gt=0, le=1e12)
    bandwidth_hz: float = number(gt=0, le=1e11)
    ramp_s: float = number(gt=0, le=1.0)
    pri_s: float = number(gt=0, le=10.0)
    sample_rate_hz: float = number(gt=0, le=1e11)
    range_offset_m: float = number(0.0, ge=0, le=1e6)

    def _check(self) -> None:
        if self.pri_s < self.ramp_s:
            raise ValueError(f"pri_s ({self.pri_s:g}) < ramp_s ({self.ramp_s:g}): chirps would overlap")

    # --- derived quantities -------------------------------------------------
    @property
    def wavelength_m(self) -> float:
        return C / self.carrier_hz

    @property
    def slope_hz_per_s(self) -> float:
        return self.bandwidth_hz / self.ramp_s

    @property
    def prf_hz(self) -> float:
        return 1.0 / self.pri_s

    @property
    def range_resolution_m(self) -> float:
        """c / 2B: the nominal resolution of the swept bandwidth."""
        return C / (2.0 * self.bandwidth_hz)

    def range_bin_m(self, n_samples: int) -> float:
        """Range spacing of one FFT bin over n_samples: c*fs / (2*S*n)."""
        return C * self.sample_rate_hz / (2.0 * self.slope_hz_per_s * n_samples)

    @property
    def range_window_m(self) -> tuple[float, float]:
        """[start, end) of ranges whose beat frequency lies in [0, fs)."""
        span = C * self.sample_rate_hz / (2.0 * self.slope_hz_per_s)
        return self.range_offset_m, self.range_offset_m + span

    def doppler_wavelength_m(self, n_samples: int) -> float:
        """Wavelength that converts slow-time frequency to radial velocity.

        A range-FFT bin's phase advances at the sweep's mid-sample frequency
        f_c + S*(n-1)/(2*fs), not at f_c: with B = 150 MHz at 77 GHz that is a
        0.1 % scale error (1.5 Doppler bins at 40 m/s in the wide preset) if
        ignored.
        """
        return C / (self.carrier_hz + self.slope_hz_per_s * (n_samples - 1) / (2.0 * self.sample_rate_hz))

    @property
    def unambiguous_velocity_mps(self) -> float:
        """Radial speeds in [-v, v) are measured without folding: lambda*PRF/4."""
        return self.wavelength_m * self.prf_hz / 4.0

    def doppler_bin_mps(self, n_chirps: int) -> float:
        return self.wavelength_m / (2.0 * n_chirps * self.pri_s)

    def fold_velocity(self, v_mps: float, n_samples: int | None = None) -> float:
        """The radial velocity the radar reports for a true one (folded into [-v_u, v_u)).

        With n_samples the fold uses the Doppler wavelength of `doppler_wavelength_m`,
        which is what the processing measures.
        """
        vu = self.unambiguous_velocity_mps if n_samples is None else self.measured_unambiguous_velocity_mps(n_samples)
        return (v_mps + vu) % (2.0 * vu) - vu

    def measured_unambiguous_velocity_mps(self, n_samples: int) -> float:
        """lambda_D * PRF / 4 with the Doppler wavelength the processing measures with."""
        return self.doppler_wavelength_m(n_samples) * self.prf_hz / 4.0

    def tip_doppler_hz(self, profile: UavProfile) -> float:
        """Maximum blade-tip micro-Doppler 2*v_tip/lambda (rotor plane seen edge-on)."""
        return 2.0 * profile.tip_speed_mps / self.wavelength_m

    def tip_aliases(self, profile: UavProfile, radial_speed_mps: float = 0.0) -> bool:
        """True when body Doppler +- tip Doppler leaves the unambiguous band [-PRF/2, PRF/2)."""
        body = 2.0 * abs(radial_speed_mps) / self.wavelength_m
        return body + self.tip_doppler_hz(profile) >= self.prf_hz / 2.0


#: Sample domains of a recorded cube (docs/format.md `domain`): IF samples of the dechirped sweep,
#: range bins, or CW (no sweep). A bundle only serves recordings of its own domain.
DOMAINS = ("if", "range", "cw")
#: Domains a bundle can be trained for: the simulator writes IF cubes of the domain's equivalent
#: waveform (`signatures.sim.domain`) and `signatures.sim.domain.as_recorded` turns them into range or CW.
TRAINABLE_DOMAINS = ("if", "range", "cw")
#: The recorded domains a bundle of each domain serves. A range-domain cube is the range spectrum
#: the IF pipeline computes first (the features skip only that FFT), so an IF bundle serves it;
#: a CW cube has no range axis and its features differ: it needs a CW bundle.
SERVES = {"if": ("if", "range"), "range": ("range",), "cw": ("cw",)}
#: Training range cover of a waveform that names none (a recording does not say): the paper's.
DEFAULT_MAX_RANGE_M = 1200.0
#: The waveform parameters that identify a bundle's radar (range offset aside: it moves with the target).
WAVEFORM_FIELDS = ("carrier_hz", "bandwidth_hz", "ramp_s", "pri_s", "sample_rate_hz")
#: How close (relative) each of WAVEFORM_FIELDS must be for a bundle to serve a recording: 1e-3.
#: A radar's clock is good to 20-100 ppm and a recording may carry a measured or rounded value (a
#: 5000.1 Hz file against a 5000.0 Hz bundle: 2e-5), so an exact match would split one radar into
#: many. The features are computed with the recording's own parameters (Hz, m/s); what a difference
#: leaves is the features counted in bins, which move by about the relative difference: 0.1 % is
#: an order below their scene-to-scene spread and 25 times inside the carrier band
#: (`signatures.classify.carrier.CARRIER_BAND_REL`, chosen on the same grounds).
WAVEFORM_REL_TOL = 1e-3


@dataclass(frozen=True)
class Preset:
    """A waveform plus the cube size it records: what a classifier bundle is trained for.

    The two shipped ones are named presets (`PRESETS`); any other radar's waveform is data,
    built by `waveform_of` (from a recording's attributes) or `load_waveform` (a JSON file) and
    named after its parameters and `key`.
    """

    name: str
    config: RadarConfig
    n_chirps: int
    n_samples: int
    max_range_m: float
    note: str = ""
    domain: str = "if"

    @property
    def window_m(self) -> float:
        lo, hi = self.config.range_window_m
        return hi - lo

    @property
    def dwell_s(self) -> float:
        return self.n_chirps * self.config.pri_s

    def with_pulses(self, n_chirps: int) -> "Preset":
        """The same waveform with a dwell of `n_chirps` pulses (e.g. a 10 s CW recording: 50000 at
        PRI 200 us); named `<name>-<n>` unless n is the preset's own."""
        n = int(n_chirps)
        if not 16 <= n <= 1_000_000 or n * self.n_samples > 1 << 25:
            raise ValueError(f"n_chirps: {n} pulses of {self.n_samples} samples is outside 16..1e6 / 2^25 cells")
        if n == self.n_chirps:
            return self
        from dataclasses import replace

        return replace(self, name=f"{self.name}-{n}", n_chirps=n)

    def with_offset(self, range_offset_m: float) -> RadarConfig:
        return self.config.replace(range_offset_m=float(range_offset_m))

    @property
    def key(self) -> str:
        return waveform_key(self.config, self.n_chirps, self.n_samples, self.domain)

    @property
    def shipped(self) -> bool:
        """True for the shipped presets themselves (whose bundles ship inside the package)."""
        return PRESETS.get(self.name) == self

    def describe(self) -> str:
        """The waveform in words, e.g. '512x80 at 77 GHz, PRI 44 us'."""
        text = (f"{self.n_chirps}x{self.n_samples} at {self.config.carrier_hz / 1e9:g} GHz, "
                f"PRI {self.config.pri_s * 1e6:.3g} us")
        return text if self.domain == "if" else f"{text}, {self.domain} domain"

    def matches(self, config: RadarConfig, n_chirps: int, n_samples: int, domain: str = "if") -> bool:
        """A bundle of this waveform serves a recording of that one: same cube size and parameters
        (range offset aside; within WAVEFORM_REL_TOL relative), a domain it serves (`SERVES`)."""
        return (self.n_chirps, self.n_samples) == (n_chirps, n_samples) and domain in SERVES[self.domain] and all(
            math.isclose(getattr(config, f), getattr(self.config, f), rel_tol=WAVEFORM_REL_TOL)
            for f in WAVEFORM_FIELDS)

    def as_json(self) -> dict[str, Any]:
        """The radar-configuration document (`load_waveform` reads it back)."""
        return {**{f: getattr(self.config, f) for f in WAVEFORM_FIELDS}, "n_chirps": self.n_chirps,
                "n_samples": self.n_samples, "max_range_m": self.max_range_m, "domain": self.domain}


def _paper() -> Preset:
    # Paper: fc 77 GHz, dR 1 m -> B 150 MHz, Rmax 1200 m. Its "sweep time 5.5 s"
    # is garbled; the usual rule is 5.5 x the round-trip time of Rmax:
    # 5.5 * 2*1200/c = 44.03 us. 80 samples spread over the ramp make one FFT bin
    # 1/T = the 1 m resolution cell, so 80 samples cover an 80 m gated window.
    # Chirps back to back (PRI = ramp) give the highest PRF the ramp allows.
    ramp = 5.5 * 2.0 * 1200.0 / C
    n_samples = 80
    cfg = RadarConfig(
        carrier_hz=77e9,
        bandwidth_hz=150e6,
        ramp_s=ramp,
        pri_s=ramp,
        sample_rate_hz=n_samples / ramp,
    )
    return Preset("paper", cfg, n_chirps=600, n_samples=n_samples, max_range_m=1200.0,
                  note="paper's numbers, sweep = 5.5 x round trip of 1200 m; blade tips alias")


def _wide() -> Preset:
    # Blade tips reach 115 m/s -> 59 kHz at 77 GHz; with +-25 m/s of body motion
    # the complex slow-time band needs PRF > 2*(59+13) kHz. PRI 6.25 us -> 160 kHz,
    # v_unamb = 156 m/s. Ramp 5 us with a range-offset (stretch) reference chirp,
    # 64 samples over the ramp -> 64 one-metre bins. 8192 chirps = 51.2 ms dwell,
    # about 4 blade-flash periods of the slowest shipped rotor.
    ramp = 5e-6
    n_samples = 64
    cfg = RadarConfig(
        carrier_hz=77e9,
        bandwidth_hz=150e6,
        ramp_s=ramp,
        pri_s=6.25e-6,
        sample_rate_hz=n_samples / ramp,
    )
    return Preset("wide", cfg, n_chirps=8192, n_samples=n_samples, max_range_m=1200.0,
                  note="PRF 160 kHz resolves blade-tip micro-Doppler without aliasing")


PRESETS: dict[str, Preset] = {p.name: p for p in (_paper(), _wide())}


def _cw_sband() -> Preset:
    # An S-band CW radar (3.3 GHz) sampled at 5 kHz (PRI 200 us); a 10 s recording is cut into
    # 0.82 s dwells of 4096 pulses (`with_pulses(50000)` for the whole 10 s). CW: one sample
    # per pulse, the FMCW-equivalent waveform of docs/format.md (ramp = PRI, B = fs = 1/PRI),
    # so the one range bin holds every range. v_unamb = lambda*PRF/4 = 113.6 m/s; blade tips of
    # a small quadcopter (~120 m/s, 2.6 kHz) alias.
    pri = 200e-6
    cfg = RadarConfig(carrier_hz=3.3e9, bandwidth_hz=1.0 / pri, ramp_s=pri, pri_s=pri, sample_rate_hz=1.0 / pri)
    return Preset("cw-sband", cfg, n_chirps=4096, n_samples=1, max_range_m=3000.0,
                  note="S-band CW, 5 kHz PRF, 0.82 s dwell; no range; no bundle ships", domain="cw")


#: Waveforms of radars the estimators are tested on (lab/accuracy.py conditions). Not shipped:
#: no classifier bundle exists for them, so nothing that lists shipped presets sees them.
EXTRA_PRESETS: dict[str, Preset] = {p.name: p for p in (_cw_sband(),)}


def waveform_key(config: RadarConfig, n_chirps: int, n_samples: int, domain: str = "if") -> str:
    """Digest of the waveform parameters (6 significant digits), cube size and domain: it names
    a waveform; `Preset.matches` is the tolerant comparison bundle lookup uses."""
    doc: dict[str, Any] = {f: f"{getattr(config, f):.6g}" for f in WAVEFORM_FIELDS}
    doc.update(n_chirps=int(n_chirps), n_samples=int(n_samples), domain=domain)
    return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()[:16]


def shipped_preset(config: RadarConfig, n_chirps: int, n_samples: int, domain: str = "if") -> Preset | None:
    """The shipped preset whose bundle serves this waveform, if any."""
    return next((p for p in PRESETS.values() if p.matches(config, n_chirps, n_samples, domain)), None)


def waveform_of(config: RadarConfig, n_chirps: int, n_samples: int, domain: str = "if",
                max_range_m: float = DEFAULT_MAX_RANGE_M) -> Preset:
    """The waveform of a cube: the shipped preset when its bundle serves it, else a new one named
    `<carrier>GHz[-<domain>]-<chirps>x<samples>-<key8>` (range offset dropped)."""
    found = shipped_preset(config, n_chirps, n_samples, domain)
    if found is not None:
        return found
    cfg = config.replace(range_offset_m=0.0)
    tag = "" if domain == "if" else f"-{domain}"
    key = waveform_key(cfg, n_chirps, n_samples, domain)
    name = f"{cfg.carrier_hz / 1e9:g}GHz{tag}-{n_chirps}x{n_samples}-{key[:8]}"
    return Preset(name, cfg, int(n_chirps), int(n_samples), float(max_range_m), domain=domain)


def recording_waveform(recording: Any) -> Preset:
    """The waveform a Recording was made with (its `domain` attribute, `if` when absent)."""
    return waveform_of(recording.config, recording.n_chirps, recording.n_samples,
                       getattr(recording, "domain", "if"))


@dataclass(frozen=True, kw_only=True)
class WaveformFile(Checked):
    """A radar-configuration JSON file: the RadarConfig fields plus cube size, range cover, domain."""

    carrier_hz: float = number()
    bandwidth_hz: float = number()
    ramp_s: float = number()
    pri_s: float = number()
    sample_rate_hz: float = number()
    range_offset_m: float = number(0.0)  # accepted (a recording's attributes), ignored: the gate follows the target
    n_chirps: int = integer(ge=16, le=1_000_000)
    n_samples: int = integer(ge=1, le=65_536)
    max_range_m: float = number(DEFAULT_MAX_RANGE_M, ge=100.0, le=1e5)
    domain: str = choice("if", "range", "cw", default="if")

    def _check(self) -> None:
        if self.n_chirps * self.n_samples > 1 << 25:
            raise ValueError(f"a {self.n_chirps}x{self.n_samples} cube exceeds 2^25 samples")
        if self.domain == "cw" and self.n_samples != 1:
            raise ValueError(f"n_samples: a CW waveform has exactly one sample per pulse, not {self.n_samples}")
        if self.domain != "cw" and self.n_samples < 8:
            raise ValueError(f"n_samples: a {self.domain}-domain waveform needs at least 8, not {self.n_samples}")


def parse_waveform(doc: object, source: str) -> Preset:
    """A waveform from a radar-configuration document; one-line SignaturesError when invalid."""
    from signatures.errors import SignaturesError

    try:
        w = WaveformFile.from_dict(doc)
        cfg = RadarConfig(**{f: getattr(w, f) for f in WAVEFORM_FIELDS})
    except Invalid as exc:
        raise SignaturesError(f"{source}: {exc.loc or 'document'}: {exc.msg}") from None
    return waveform_of(cfg, w.n_chirps, w.n_samples, w.domain, w.max_range_m)


def load_waveform(path: Path) -> Preset:
    """The waveform described by a radar-configuration JSON file (docs/waveform.md)."""
    from signatures.errors import SignaturesError

    try:
        doc = loads_json(Path(path).read_text())
    except OSError as exc:
        raise SignaturesError(f"{path}: cannot read radar configuration ({exc.strerror})") from None
    except JsonTooDeep as exc:
        raise SignaturesError(f"{path}: radar configuration: {exc}") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise SignaturesError(f"{path}: radar configuration is not JSON ({exc})") from None
    return parse_waveform(doc, str(path))


def get_preset(name: str) -> Preset:
    from signatures.errors import SignaturesError

    found = PRESETS.get(name) or EXTRA_PRESETS.get(name)
    if found is None:
        raise SignaturesError(f"unknown preset {name!r} (known: {', '.join([*PRESETS, *EXTRA_PRESETS])})")
    return found


def describe(config: RadarConfig, n_chirps: int, n_samples: int,
             profiles: dict[str, UavProfile] | None = None) -> dict[str, object]:
    """The validator's report: what this waveform can and cannot measure."""
    lo, hi = config.range_window_m
    report: dict[str, object] = {
        "wavelength_m": config.wavelength_m,
        "range_resolution_m": config.range_resolution_m,
        "range_bin_m": config.range_bin_m(n_samples),
        "range_window_m": [lo, hi],
        "prf_hz": config.prf_hz,
        "unambiguous_velocity_mps": config.unambiguous_velocity_mps,
        "doppler_bin_mps": config.doppler_bin_mps(n_chirps),
        "dwell_s": n_chirps * config.pri_s,
    }
    if profiles:
        report["blade_tips"] = {
            slug: {
                "tip_speed_mps": p.tip_speed_mps,
                "tip_doppler_hz": config.tip_doppler_hz(p),
                "aliases_when_hovering": config.tip_aliases(p),
            }
            for slug, p in profiles.items()
        }
    return report
