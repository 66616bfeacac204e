"""A site's enrolment recording as `authn models enrol` learns from it (docs/classifiers.md).

The recording is labelled (LABELS.csv, or its Remote ID serial's registered model) and its
features are extracted as `authn check` extracts them: gated at the range its Remote ID
declares, so the site bundle learns the features it will be asked about. Here, not in
`signatures.enrol`, because labelling reads the registry and gating the Remote ID (layers).
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["site_sample"]


def site_sample(path: Path, model: str | None, db, recording=None):  # -> (SiteSample, Preset)
    """Read one recording, label it (its Remote ID serial's registered model when `model` is None),
    and extract its features as `authn check` would: gated at the range its Remote ID declares."""
    from dataclasses import asdict

    from authn.evidence import read_claim
    from authn.kinematics import expected_from_radar
    from core.errors import AuthnException
    from core.digest import file_sha256
    from signatures.enrol import EnrolError, SiteSample
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
