"""`authn register` and `authn registry list/show/revoke/import/export/models`."""

from __future__ import annotations

import json
import sys
from datetime import datetime, timedelta, timezone
from pathlib import Path
from typing import Optional

import typer

from core.parsing import parse_iso_time
from core.textsafe import printable


registry_app = typer.Typer(help="Inspect and change the registry of authorised UAVs.",
                           no_args_is_help=True)

_PROFILE_OPTS = ("rotors", "arms", "blades_per_rotor", "blade_length_m", "rotor_rate_hz",
                 "propeller_distance_m")


def _time(value: Optional[str], option: str) -> Optional[datetime]:
    from core.errors import AuthnError

    if value is None:
        return None
    return parse_iso_time(value, option, error=AuthnError)


#: `authn register` without --valid-from starts the validity window this long before now: the
#: common order (record or simulate a flight, then register the drone) must not reject it.
REGISTRATION_GRACE = timedelta(hours=24)


def _default_valid_from() -> datetime:
    return datetime.now(timezone.utc) - REGISTRATION_GRACE


def _validated(cls, **fields):
    """Build a `core.checked` value (UavProfile, NewIdentity); its first error becomes a one-line
    RegistryError."""
    from core.checked import Invalid
    from registry.errors import RegistryError
    from registry.store import describe_validation_error

    try:
        return cls(**fields)
    except Invalid as exc:
        raise RegistryError(describe_validation_error(exc)) from None


def _record_json(rec) -> dict:
    return rec.to_dict(json=True)


def register_cmd(
    ctx: typer.Context,
    serial: Optional[str] = typer.Option(None, "--serial",
                                         help="Remote ID UAS ID (ANSI/CTA-2063-A serial by default)."),
    model: str = typer.Option(..., "--model", help="Model profile slug (m600, m300, phantom4 or a new one)."),
    id_type: str = typer.Option("serial", "--id-type", help="serial | caa_registration | utm_uuid | specific_session."),
    operator_id: Optional[str] = typer.Option(None, "--operator-id", help="Operator registration ID (max 20 chars)."),
    public_key: Optional[Path] = typer.Option(None, "--public-key",
                                              help="Ed25519 public key file: 32 raw bytes, hex or PEM."),
    valid_from: Optional[str] = typer.Option(None, "--valid-from",
                                             help="ISO 8601 start (naive = UTC; default: 24 h before now, so that a "
                                                  "return recorded shortly before registering is inside the window)."),
    valid_until: Optional[str] = typer.Option(None, "--valid-until", help="ISO 8601 end (default: open-ended)."),
    notes: Optional[str] = typer.Option(None, "--notes", help="Free text."),
    model_name: Optional[str] = typer.Option(None, "--model-name", help="New model: display name."),
    rotors: Optional[int] = typer.Option(None, "--rotors", help="New model: number of rotors."),
    arms: Optional[int] = typer.Option(None, "--arms", help="New model: number of arms (default: rotors)."),
    blades_per_rotor: int = typer.Option(2, "--blades-per-rotor", help="New model: blades per rotor."),
    blade_length_m: Optional[float] = typer.Option(None, "--blade-length", help="New model: blade length, m."),
    rotor_rate_hz: Optional[float] = typer.Option(None, "--rotor-rate", help="New model: rotor rate, Hz."),
    propeller_distance_m: Optional[float] = typer.Option(None, "--propeller-distance",
                                                         help="New model: propeller distance, m."),
    as_json: bool = typer.Option(False, "--json", help="Print the registered identity as JSON."),
) -> None:
    """Register an authorised UAV identity, and optionally a new model profile.

    Giving --rotors/--blade-length/--rotor-rate/--propeller-distance (and
    --model-name) registers --model as a new airframe first; without --serial
    only the profile is registered. Everything is validated before anything is
    written, and profile + identity are one transaction.

    Example: authn register --serial 1581F5FJD12345678901 --model m300 --operator-id FIN87astrdge12k

    Example: authn register --model x8 --model-name "Octo X8" --rotors 8 --arms 4 --blade-length 0.38 \\
      --rotor-rate 45 --propeller-distance 1.2
    """
    from registry.errors import RegistryError
    from registry.keys import read_public_key
    from registry.store import NewIdentity
    from signatures.profiles import UavProfile

    new_profile = None
    physical = (rotors, blade_length_m, rotor_rate_hz, propeller_distance_m)
    if model_name is not None or any(v is not None for v in physical):
        if model_name is None or any(v is None for v in physical):
            raise RegistryError("a new model needs --model-name, --rotors, --blade-length, "
                                "--rotor-rate and --propeller-distance")
        new_profile = _validated(
            UavProfile, slug=model, name=model_name, rotors=rotors, arms=arms or rotors,
            blades_per_rotor=blades_per_rotor, blade_length_m=blade_length_m,
            rotor_rate_hz=rotor_rate_hz, propeller_distance_m=propeller_distance_m)
    new = None
    if serial is not None:
        new = _validated(
            NewIdentity, serial=serial, id_type=id_type, model=model, operator_id=operator_id,
            public_key=read_public_key(public_key) if public_key else None,
            valid_from=_time(valid_from, "--valid-from") or _default_valid_from(),
            valid_until=_time(valid_until, "--valid-until"),
            notes=notes)
    elif new_profile is None:
        raise RegistryError("nothing to register: give --serial (and/or a new model's parameters)")

    from registry.dbapi import transaction
    from registry.store import register_identity, register_profile

    with transaction(ctx.obj.db_url) as db:
        if new_profile is not None:
            register_profile(db, new_profile)
        rec = register_identity(db, new) if new is not None else None
    if as_json:
        out = {"profile": new_profile.to_dict() if new_profile else None,
               "identity": _record_json(rec) if rec else None}
        typer.echo(json.dumps(out, indent=2))
        return
    if new_profile is not None:
        typer.echo(printable(f"registered model {new_profile.slug} ({new_profile.name})"))
    if rec is not None:
        typer.echo(printable(f"registered {rec.serial} ({rec.id_type}, model {rec.model}, {rec.status})"))


def _table(records, title: str):
    from rich.table import Table

    from core.textsafe import cell

    t = Table(title=title, caption="all fields: `authn registry show SERIAL` or --json")
    t.add_column("serial", no_wrap=True, min_width=16)  # an identifier: never split (a DRIP session ID is 34)
    for col in ("model", "status", "valid (UTC)"):
        t.add_column(col, no_wrap=True)
    t.add_column("key", no_wrap=True)
    for r in records:
        until = r.valid_until.strftime("%Y-%m-%d") if r.valid_until else ""
        t.add_row(cell(r.serial), cell(r.model), r.status, f"{r.valid_from:%Y-%m-%d}..{until}",
                  "yes" if r.public_key else "")
    return t


@registry_app.command("list")
def list_cmd(
    ctx: typer.Context,
    status: Optional[str] = typer.Option(None, "--status", help="Only 'active' or 'revoked'."),
    as_json: bool = typer.Option(False, "--json", help="Print a JSON array."),
) -> None:
    """List registered identities.

    Example: authn registry list --status active --json
    """
    from registry.dbapi import transaction
    from registry.errors import RegistryError
    from registry.store import list_identities

    if status not in (None, "active", "revoked"):
        raise RegistryError(f"--status {status!r}: expected active or revoked")
    with transaction(ctx.obj.db_url) as db:
        records = list_identities(db, status)
    if as_json:
        typer.echo(json.dumps([_record_json(r) for r in records], indent=2))
        return
    from authn.cli.output import print_table

    print_table(_table(records, f"{len(records)} registered identities"))


@registry_app.command("show")
def show_cmd(
    ctx: typer.Context,
    serial: str = typer.Argument(..., help="UAS ID to show."),
    as_json: bool = typer.Option(False, "--json", help="Print one JSON object."),
) -> None:
    """Show one identity with its declared model's physical parameters.

    Example: authn registry show 1581F5FJD12345678901 --json
    """
    from registry.dbapi import transaction
    from registry.errors import RegistryError
    from registry.store import get_identity

    with transaction(ctx.obj.db_url) as db:
        rec = get_identity(db, serial)
    if rec is None:
        raise RegistryError(f"serial {serial}: not registered")
    if as_json:
        typer.echo(json.dumps(_record_json(rec), indent=2))
        return
    from rich.table import Table

    from authn.cli.output import print_table
    from core.textsafe import cell

    t = Table(title=cell(rec.serial), show_header=False)  # notes, names: imported text, escaped
    t.add_column("field", no_wrap=True)
    t.add_column("value", overflow="fold")
    data = _record_json(rec)
    profile = data.pop("profile")
    for k, v in data.items():
        t.add_row(k, cell(v))
    for k, v in profile.items():
        t.add_row(f"profile.{k}", cell(v))
    print_table(t)


@registry_app.command("revoke")
def revoke_cmd(
    ctx: typer.Context,
    serial: str = typer.Argument(..., help="UAS ID to revoke."),
    reason: Optional[str] = typer.Option(None, "--reason", help="Appended to the notes."),
) -> None:
    """Revoke an identity (kept, marked revoked: checks against it are rejected).

    Example: authn registry revoke 1581F5FJD12345678901 --reason "reported stolen"
    """
    from registry.dbapi import transaction
    from registry.store import revoke_identity

    with transaction(ctx.obj.db_url) as db:
        rec = revoke_identity(db, serial, reason)
    typer.echo(printable(f"revoked {rec.serial}"))


_CSV_COLUMNS_HELP = "serial, id_type, model, operator_id, valid_from, valid_until, notes, status, public_key"


@registry_app.command("import")
def import_cmd(
    ctx: typer.Context,
    file: Path = typer.Argument(..., help="A JSON export (authn-registry/1) or a CSV file; - for stdin."),
    fmt: str = typer.Option("auto", "--format", help="auto (JSON if the file starts with '{', else CSV), json or csv."),
    skip_existing: bool = typer.Option(False, "--skip-existing",
                                       help="Leave serials already registered as they are (a re-import is a "
                                            "no-op) instead of refusing the file."),
) -> None:
    """Restore a JSON export or register every row of a CSV file: all or nothing, one transaction.

    JSON is what `authn registry export` writes: model profiles and identities
    with every field (status, public key, timestamps). Missing profiles are
    added, identical registered ones accepted, conflicting ones refused.
    Revoked identities stay revoked.

    CSV columns: serial, id_type, model, operator_id, valid_from, valid_until, notes, status, public_key
    (header row required; only serial and model must be filled; id_type
    defaults to serial, status to active; public_key is 64 hex digits; times
    are ISO 8601, naive = UTC; files without status/public_key still import).
    CSV carries no model profiles: a custom model must be registered first,
    or use a JSON export.

    Example: authn registry import registry.json

    Example (a re-import adds only new serials): authn registry import registry.json --skip-existing

    Example: authn registry import fleet.csv
    """
    from registry.dbapi import transaction
    from registry.errors import RegistryError
    from registry.store import import_records, parse_import

    if fmt not in ("auto", "json", "csv"):
        raise RegistryError(f"--format {fmt!r}: expected auto, json or csv")
    try:
        if str(file) == "-":
            text = sys.stdin.read()
        else:
            text = file.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise RegistryError(f"{file}: cannot read ({getattr(exc, 'strerror', None) or exc})") from None
    try:
        data = parse_import(text, fmt)  # validate everything before touching the database
    except RegistryError as exc:
        raise RegistryError(f"{file}: {exc}") from None
    with transaction(ctx.obj.db_url) as db:
        try:
            result = import_records(db, data, skip_existing=skip_existing)
        except RegistryError as exc:
            raise RegistryError(f"{file}: {exc}") from None
    msg = f"imported {result.identities} identities from {file}"
    if skip_existing:
        msg += f", skipped {result.identities_skipped} already registered"
    if data.format == "json":
        msg += (f" ({result.profiles_added} new model profiles, "
                f"{result.profiles_existing} already registered)")
    typer.echo(msg)


@registry_app.command("export")
def export_cmd(
    ctx: typer.Context,
    out: Optional[Path] = typer.Option(None, "--out", help="Write here instead of stdout."),
    fmt: Optional[str] = typer.Option(None, "--format", help="json (default; csv when --out ends in .csv) or csv."),
) -> None:
    """Write the registry: JSON (lossless, default) or CSV.

    JSON ({"format": "authn-registry/1", "profiles": [...], "identities": [...]})
    holds every model profile and every identity field: status, public key
    (hex), validity, notes, created_at/updated_at. `authn registry import`
    restores it into another database exactly.

    CSV (serial, id_type, model, operator_id, valid_from, valid_until, notes, status, public_key)
    is for spreadsheets and bulk onboarding: it carries NO model profiles and no
    created_at/updated_at, so identities of a custom model do not import into a
    fresh registry from it; use JSON for backups and migrations.

    Example: authn registry export --out registry.json

    Example: authn registry export --format csv --out fleet.csv
    """
    from registry.dbapi import transaction
    from registry.errors import RegistryError
    from registry.store import custom_profiles, export_csv, export_json

    if fmt is None:
        fmt = "csv" if out is not None and out.suffix.lower() == ".csv" else "json"
    if fmt not in ("json", "csv"):
        raise RegistryError(f"--format {fmt!r}: expected json or csv")
    with transaction(ctx.obj.db_url) as db:
        if fmt == "json":
            text = export_json(db)
        else:
            text = export_csv(db)
            custom = [p.slug for p in custom_profiles(db)]
    if fmt == "csv" and custom:
        typer.echo(f"warning: CSV carries no model profiles; custom model(s) {', '.join(custom)} "
                   "must be registered before this file imports elsewhere (use --format json)",
                   err=True)
    if out is None:
        typer.echo(text, nl=False)
        return
    try:
        out.write_text(text, encoding="utf-8")
    except OSError as exc:
        raise RegistryError(f"{out}: cannot write ({exc.strerror})") from None


@registry_app.command("models")
def models_cmd(
    ctx: typer.Context,
    as_json: bool = typer.Option(False, "--json", help="Print a JSON array."),
) -> None:
    """List the model profiles (declared airframes) in the registry.

    Example: authn registry models --json
    """
    from registry.dbapi import transaction
    from registry.store import list_profiles

    with transaction(ctx.obj.db_url) as db:
        profiles = list_profiles(db)
    if as_json:
        typer.echo(json.dumps([p.to_dict() for p in profiles], indent=2))
        return
    from rich.table import Table

    from authn.cli.output import print_table
    from core.textsafe import cell

    t = Table(title="model profiles")
    t.add_column("slug", no_wrap=True)
    t.add_column("name", overflow="fold")
    for col in ("rotors", "arms", "blades", "blade m", "rotor Hz", "prop. dist. m"):
        t.add_column(col, justify="right", no_wrap=True)
    for p in profiles:
        t.add_row(cell(p.slug), cell(p.name), str(p.rotors), str(p.arms), str(p.blades_per_rotor),
                  f"{p.blade_length_m:g}", f"{p.rotor_rate_hz:g}", f"{p.propeller_distance_m:g}")
    print_table(t)
