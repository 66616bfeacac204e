"""A site's enrolment recording as `authn models enrol` learns from it (docs/classifiers.md).

The recording is labelled (LABELS.csv, or its Remote ID serial's registered model) and its
features are extracted as `authn check` extracts them: gated at the range its Remote ID
declares, so the site bundle learns the features it will be asked about. Here, not in
`signatures.train.enrol`, because labelling reads the registry and gating the Remote ID (layers).

A carrier-stepped radar enrols as one waveform (`on_one_waveform`): its recordings' carriers
within the carrier band of the middle one, their Doppler-frequency features put on that carrier
as a check puts them (`signatures.classify.carrier`).
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["on_one_waveform", "site_sample"]


def site_sample(path: Path, model: str | None, db, recording=None):  # -> (SiteSample, Preset)
    """Read one recording, label it (its Remote ID serial's registered model when `model` is None),
    and extract its features as `authn check` would: gated at the range its Remote ID declares."""
    from dataclasses import asdict

    from authn.evidence import read_claim
    from authn.kinematics import expected_from_radar
    from core.errors import AuthnException
    from core.digest import file_sha256
    from signatures.train.site_samples import EnrolError, SiteSample
    from signatures.features import extract
    from signatures.radar import recording_waveform
    from signatures.recording import read_recording

    rec = recording if recording is not None else read_recording(path)
    claim = None
    try:
        claim = read_claim(rec, None)
    except AuthnException:
        if model is None:
            raise EnrolError(f"{path}: no Remote ID serial to label it by (give --labels LABELS.csv)") from None
    if model is None:
        ident = db.identity(claim.serial)
        if ident is None:
            raise EnrolError(f"{path}: Remote ID serial {claim.serial} is not registered "
                             "(register it, or give --labels)")
        if ident.status != "active":
            raise EnrolError(f"{path}: Remote ID serial {claim.serial} is {ident.status}, not active")
        model = ident.model
    gate = None
    if claim is not None and claim.state is not None and rec.domain != "cw":
        exp = expected_from_radar(claim.state, rec.site.lat_deg, rec.site.lon_deg, rec.site.alt_m, rec.start_time)
        lo, hi = rec.config.range_window_m
        gate = exp.range_m if lo <= exp.range_m < hi else None
    feats = extract(rec, expected_range_m=gate)
    physics = {k: float(v) for k, v in feats.physics.items()}
    physics.update({k: float(v) for k, v in asdict(feats.features).items() if k not in physics})
    sample = SiteSample(name=str(path), sha256=file_sha256(path), model=model,
                        features=feats.as_array().astype("float32"), physics=physics, detected=bool(feats.detected))
    return sample, recording_waveform(rec)


def on_one_waveform(read: list, base=None):  # ([(SiteSample, Preset)], Preset | None) -> (Preset, samples, carriers)
    """The one waveform the recordings enrol as (`base` where given: the bundle `--add` extends;
    else `signatures.classify.carrier.band_waveform`), the samples with their feature vectors as a radar
    of that waveform's carrier would have measured them (`signatures.classify.carrier.normalise`: what a
    check does before the classifier sees them; the physics estimates, in rates and m/s, stay as
    measured, as the check's verification reads them), and each sample's carrier (Hz).
    A recording the waveform does not serve is an EnrolError naming the waveforms."""
    from dataclasses import replace

    import numpy as np

    from signatures.classify.carrier import CARRIER_BAND_REL, band_waveform, carrier_ratio, normalise
    from signatures.train.site_samples import EnrolError
    from signatures.features import FEATURE_NAMES

    waveforms = {wf.key: wf for _, wf in read}
    target = base if base is not None else band_waveform(list(waveforms.values()))
    if target is None or any(carrier_ratio(target, wf) is None for wf in waveforms.values()):
        described = "; ".join(w.describe() for w in waveforms.values())
        into = f" into {base.describe()}" if base is not None else ""
        raise EnrolError(f"the recordings are of {len(waveforms)} waveforms ({described}) that no one bundle "
                         f"serves{into} (carriers within +-{CARRIER_BAND_REL:.1%} of their middle, the rest "
                         "alike): enrol each waveform's recordings on their own")
    carriers = [float(wf.config.carrier_hz) for _, wf in read]
    out = [replace(s, features=np.asarray(normalise(s.features[None, :], FEATURE_NAMES, target.config,
                                                    target.n_samples, f)[0], dtype=np.float32))
           for (s, _), f in zip(read, carriers)]
    return target, out, carriers
