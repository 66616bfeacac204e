"""`authn keys ...`: Ed25519 keys for DRIP-signed Remote ID (RFC 9374 DETs)."""

from __future__ import annotations

import json
from pathlib import Path

import typer

keys_app = typer.Typer(help="Keys for signed Remote ID (IETF DRIP).", no_args_is_help=True)


@keys_app.command("generate")
def generate_cmd(
    out: Path = typer.Option(..., "--out", help="Private key file to write (PEM, mode 0600); the public key "
                                               "goes beside it as NAME.pub.pem."),
    raa: int = typer.Option(16376, "--raa", help="Registered Assigning Authority of the DET (14 bits)."),
    hda: int = typer.Option(1, "--hda", help="HHIT Domain Authority of the DET (14 bits)."),
    as_json: bool = typer.Option(False, "--json", help="Print JSON."),
) -> None:
    """Generate an Ed25519 key pair and its DRIP Entity Tag (RFC 9374, EdDSA/cSHAKE128 suite).

    Register the public key with the drone's identity, then sign what it broadcasts:

    Example: authn keys generate --out ua.pem && authn register --serial 1581BDEM00000099 --model m300 --public-key ua.pub.pem
    """
    from authn.uakeys import generate, write
    from registry.remoteid.drip import det_to_text

    key = generate(raa, hda)
    private_path, public_path = write(key, out)
    doc = {"private_key": str(private_path), "public_key_file": str(public_path), "public_key": key.public_raw.hex(),
           "det": det_to_text(key.det), "det_hex": key.det.hex(), "session_id": key.session_id}
    if as_json:
        typer.echo(json.dumps(doc, indent=2))
        return
    for name, value in doc.items():
        typer.echo(f"{name:16} {value}")
