"""`authn rid decode`: ASTM F3411 Remote ID messages from hex or from a capture file."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

import typer


rid_app = typer.Typer(help="Remote ID (ASTM F3411 / Open Drone ID) tools.", no_args_is_help=True)


def _summary(msg) -> str:
    fields = msg.model_dump(mode="json", exclude={"type", "protocol_version"})
    return ", ".join(f"{k}={v}" for k, v in fields.items() if v not in (None, "", 0) or k == "page")


@rid_app.command("decode")
def decode_cmd(
    messages: Optional[list[str]] = typer.Argument(None, help="Messages as hex (25 bytes, or a message pack)."),
    pcap: Optional[Path] = typer.Option(None, "--pcap", help="pcap/pcapng capture (Wi-Fi beacon/NAN, Bluetooth LE)."),
    as_json: bool = typer.Option(False, "--json", help="Print a JSON array."),
) -> None:
    """Decode F3411 broadcast messages (all types, protocol versions 0-2).

    Unknown values decode to null; units are degrees, metres, m/s, seconds
    and UTC times. With --pcap, every Open Drone ID frame of the capture is
    decoded with its capture time and transport.

    Example: authn rid decode 0012314135383146354650344431323334353637383930414200000000 --json

    Example: authn rid decode --pcap odid_wifi_bcn_sample.pcap
    """
    from registry.remoteid.errors import RemoteIdError

    if bool(messages) == bool(pcap):
        raise RemoteIdError("give hex messages or --pcap FILE (one of them)")
    if pcap is not None:
        from registry.remoteid.capture import read_capture

        found = read_capture(pcap)
        if as_json:
            typer.echo(json.dumps([json.loads(c.model_dump_json()) for c in found], indent=2))
            return
        rows = [(str(c.frame), c.captured_at.isoformat() if c.captured_at else "", c.transport, m)
                for c in found for m in _flat(c.message)]
    else:
        from registry.remoteid.codec import decode_hex

        decoded = [decode_hex(h) for h in messages]
        if as_json:
            typer.echo(json.dumps([m.model_dump(mode="json") for m in decoded], indent=2))
            return
        rows = [(str(i), "", "", m) for i, d in enumerate(decoded, 1) for m in _flat(d)]
    from rich.console import Console
    from rich.table import Table

    t = Table(title=f"{len(rows)} Remote ID messages")
    for col in ("#", "captured", "transport", "type", "v", "fields"):
        t.add_column(col, overflow="fold")
    for frame, ts, transport, m in rows:
        t.add_row(frame, ts, transport, m.type, str(m.protocol_version), _summary(m))
    Console().print(t)


def _flat(msg) -> list:
    return list(msg.messages) if msg.type == "message_pack" else [msg]
