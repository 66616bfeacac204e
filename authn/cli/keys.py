"""`authn keys ...`: Ed25519 keys for DRIP-signed Remote ID (RFC 9374 DETs), and the API keys of `authn serve`."""

from __future__ import annotations

import json
from pathlib import Path

import typer

from authn.cli.groups import subgroup

keys_app = typer.Typer(help="Keys for signed Remote ID (IETF DRIP).", no_args_is_help=True)

#: The options of `generate` and `show` (the DET's authorities and the output form are both's).
RAA_OPTION = typer.Option(16376, "--raa", help="Registered Assigning Authority of the DET (14 bits).")
HDA_OPTION = typer.Option(1, "--hda", help="HHIT Domain Authority of the DET (14 bits).")
JSON_OPTION = typer.Option(False, "--json", help="Print JSON.")
OUT_OPTION = typer.Option(..., "--out", help="Private key file to write (PEM, mode 0600); the public key goes "
                                             "beside it as NAME.pub.pem.")
PUBLIC_KEY_OPTION = typer.Option(..., "--public-key", help="Public key: a file (PEM, 32 raw bytes or 64 hex digits) "
                                                           "or the 64 hex digits themselves.")


@keys_app.command("generate")
def generate_cmd(
    out: Path = OUT_OPTION, raa: int = RAA_OPTION, hda: int = HDA_OPTION, as_json: bool = JSON_OPTION,
) -> None:
    """Generate an Ed25519 key pair and its DRIP Entity Tag (RFC 9374, EdDSA/cSHAKE128 suite).

    Register the public key with the drone's identity, then sign what it broadcasts:

    Example: authn keys generate --out ua.pem && \\
      authn register --serial 1581BDEM00000099 --model m300 --public-key ua.pub.pem
    """
    from authn.uakeys import generate, write
    from remoteid.drip import det_to_text

    key = generate(raa, hda)
    private_path, public_path = write(key, out)
    doc = {"private_key": str(private_path), "public_key_file": str(public_path), "public_key": key.public_raw.hex(),
           "det": det_to_text(key.det), "det_hex": key.det.hex(), "session_id": key.session_id}
    _emit(doc, as_json)


@keys_app.command("show")
def show_cmd(
    public_key: str = PUBLIC_KEY_OPTION, raa: int = RAA_OPTION, hda: int = HDA_OPTION, as_json: bool = JSON_OPTION,
) -> None:
    """Print the DRIP Entity Tag and session ID of an existing public key (RFC 9374).

    DETs printed before the RFC 9575 example fix hashed the key in another form and differ:
    this prints the one checks use now (docs/drip.md).

    Example: authn keys show --public-key ua.pub.pem
    """
    from authn.uakeys import det_of, read_public_key_arg, session_id_of
    from remoteid.drip import det_to_text

    key = read_public_key_arg(public_key)
    det = det_of(key, raa, hda)
    doc = {"public_key": key.hex(), "det": det_to_text(det), "det_hex": det.hex(),
           "session_id": session_id_of(det)}
    _emit(doc, as_json)


def _emit(doc: dict, as_json: bool) -> None:
    """A key's facts: JSON, or one `name value` line each."""
    if as_json:
        typer.echo(json.dumps(doc, indent=2))
        return
    for name, value in doc.items():
        typer.echo(f"{name:16} {value}")


api_app = subgroup(keys_app, "api", "API keys of `authn serve` (the secret is shown once; only its hash is stored).",
                   "authn keys api create --role operator --json")


@api_app.command("create")
def api_create_cmd(
    ctx: typer.Context,
    role: str = typer.Option(..., "--role", help="operator (checks, audit reads) or admin (everything)."),
    name: str | None = typer.Option(None, "--name", help="A label to tell keys apart."),
    as_json: bool = JSON_OPTION,
) -> None:
    """Create an API key and print its secret, once: store it now, it cannot be shown again.

    Example: authn keys api create --role operator --name radar-site-1
    """
    from authn.service.keys import create_key

    info, token = create_key(ctx.obj.db_url, role, name)
    if as_json:
        typer.echo(json.dumps({**info.to_json(), "token": token}, indent=2))
        return
    typer.echo(f"API key {info.id} ({info.role}{', ' + info.name if info.name else ''}) created; its secret, "
               "shown only now:", err=True)
    typer.echo(token)


@api_app.command("list")
def api_list_cmd(ctx: typer.Context, as_json: bool = JSON_OPTION) -> None:
    """List API keys (never their secrets).

    Example: authn keys api list
    """
    from authn.service.keys import list_keys

    keys = list_keys(ctx.obj.db_url)
    if as_json:
        typer.echo(json.dumps([k.to_json() for k in keys], indent=2))
        return
    for k in keys:
        state = f"revoked {k.revoked_at:%Y-%m-%d %H:%M}" if k.revoked_at else "active"
        typer.echo(f"{k.id:>5}  {k.role:8}  {state:24}  {k.name or ''}")


@api_app.command("revoke")
def api_revoke_cmd(ctx: typer.Context, key_id: int = typer.Argument(..., help="Key id (`authn keys api list`).")
                   ) -> None:
    """Revoke an API key: the server refuses it (401) from its next request.

    Example: authn keys api revoke 3
    """
    from authn.service.keys import revoke_key

    info = revoke_key(ctx.obj.db_url, key_id)
    typer.echo(f"API key {info.id} revoked")
