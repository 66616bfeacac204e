"""`authn features`: the feature vector of a return (the laboratory adds `accuracy` and `score`:
lab/cli/features.py)."""

from __future__ import annotations

import json
from pathlib import Path

import typer

from authn.cli.plugins import PluginGroup


features_app = typer.Typer(help="Micro-Doppler features of a return (estimator accuracy: with the laboratory).",
                           no_args_is_help=True, cls=PluginGroup)


@features_app.command("show")
def show(
    file: Path = typer.Argument(..., help="Recorded return (.h5/.npz)."),
    expected_range: float | None = typer.Option(None, "--expected-range", help="Gate at this range, m."),
    as_json: bool = typer.Option(False, "--json", help="One JSON object."),
) -> None:
    """Print the physics the decision's verification compares with the claim (flash rate, tip
    speed, rotors seen), then the named feature vector the classifier reads (order =
    signatures.features.FEATURE_NAMES); a count verification does not read is labelled so.

    Example: authn features show m300.h5 --expected-range 500 --json
    """
    from signatures.features import FEATURE_NAMES, extract
    from signatures.recording import read_recording
    from signatures.classify.verify import PHYSICS_READS

    rec = read_recording(file)
    res = extract(rec, expected_range_m=expected_range)
    values: dict[str, float | None] = dict(zip(FEATURE_NAMES, (float(x) for x in res.as_array())))
    unmeasured = _unmeasured(values, getattr(rec, "domain", "if"))
    both = {**values, **res.physics}
    physics = {k: both[k] for k in PHYSICS_READS if k in both and k not in unmeasured}
    if as_json:  # an unmeasured value is null (the classifier reads it as 0)
        typer.echo(json.dumps({"detected": res.detected, "gate": list(res.gate), "verification_reads": physics,
                               "features": {k: None if k in unmeasured else v for k, v in values.items()},
                               "unmeasured": sorted(unmeasured), "physics": dict(res.physics),
                               "classifier_only": {k: v for k, v in CLASSIFIER_ONLY.items() if k in values}}))
        return
    typer.echo(f"detected: {res.detected}   gate: range bins {res.gate[0]}..{res.gate[1] - 1}")
    typer.echo("physics the verification compares with the claim:")
    for name, v in physics.items():
        typer.echo(f"{name:26s} {v:14.6g}")
    typer.echo("feature vector (the classifier's input):")
    for name, v in values.items():
        if name in unmeasured:
            typer.echo(f"{name:26s} {'n/a':>14s}   ({unmeasured[name]})")
        else:
            note = f"   ({CLASSIFIER_ONLY[name]})" if name in CLASSIFIER_ONLY else ""
            typer.echo(f"{name:26s} {v:14.6g}{note}")


#: features a reader could take for the physics the decision uses but that verification does not
#: read, and what it reads instead
CLASSIFIER_ONLY = {"rotor_count": "classifier input only: verification counts rotors_seen",
                   "rotor_count_std": "classifier input only: verification reads rotors_seen_std"}


def _unmeasured(values: dict, domain: str) -> dict[str, str]:
    """Features this return cannot measure, with why: the blade length when the blade tips alias
    (the classifier gets 0), the range features of a CW recording (no range axis)."""
    out: dict[str, str] = {}
    if values.get("tip_aliased"):
        out.update({k: "blade tips alias" for k in ("blade_length_m", "blade_length_std_m")})
    if domain == "cw":
        out.update({k: "CW: no range axis" for k in ("mean_range_m", "std_range_m", "range_m", "range_std_m")})
    return {k: v for k, v in out.items() if k in values}
