"""`authn rid decode`: ASTM F3411 Remote ID messages from hex or from a capture file."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

import typer


rid_app = typer.Typer(help="Remote ID (ASTM F3411 / Open Drone ID) tools.", no_args_is_help=True)


def _summary(msg) -> str:
    fields = msg.to_dict(json=True, exclude=("type", "protocol_version"))
    return ", ".join(f"{k}={v}" for k, v in fields.items() if v not in (None, "", 0) or k == "page")


@rid_app.command("decode")
def decode_cmd(
    messages: Optional[list[str]] = typer.Argument(None, help="Messages as hex (25 bytes, or a message pack)."),
    pcap: Optional[Path] = typer.Option(None, "--pcap", help="pcap/pcapng capture (Wi-Fi beacon/NAN, Bluetooth LE)."),
    as_json: bool = typer.Option(False, "--json", help="Print a JSON array."),
    public_key: Optional[str] = typer.Option(None, "--public-key",
                                             help="Verify DRIP authentication pages (RFC 9575) with this Ed25519 key: "
                                                  "a key file (PEM, 32 raw bytes or 64 hex digits) or the 64 hex "
                                                  "digits themselves."),
    at: Optional[str] = typer.Option(None, "--at",
                                     help="Time the signatures must be valid at (ISO 8601; default now)."),
) -> None:
    """Decode F3411 broadcast messages (all types, protocol versions 0-2).

    Unknown values decode to null; units are degrees, metres, m/s, seconds
    and UTC times. With --pcap (or a pcap/pcapng file, known by its magic number, given
    in place of the messages), every Open Drone ID frame of the capture is decoded with
    its capture time and transport.

    Authentication pages are reassembled and their DRIP structures (RFC 9575: Link,
    Wrapper, Manifest, Frame) listed; with --public-key the signatures are verified.

    Example: authn rid decode 0012313538314635464a443132333435363738393031000000 --json

    Example: authn rid decode --pcap odid_wifi_bcn_sample.pcap

    Example: authn rid decode $(cat pages.hex) --public-key ua.pub.pem

    A signature that verifies outside its validity window is reported as expired or
    not-yet-valid ("verified-but-expired"), never as invalid. Pages ending with a
    forward-error-correction page are checked (parity) and one lost page is rebuilt.
    """
    from remoteid.errors import RemoteIdError

    if messages and pcap is None and len(messages) == 1:
        pcap = _capture_given_as_message(messages[0])
        messages = None if pcap is not None else messages
    if bool(messages) == bool(pcap):
        raise RemoteIdError("give hex messages or --pcap FILE (one of them)")
    title = ""
    if pcap is not None:
        from remoteid.capture import read_capture

        found = read_capture(pcap)
        title = f" in {pcap.name} ({_format_of(pcap)})"
        wire = [m for c in found for m in _flat(c.message)]  # re-encoded when verified (canonical senders)
        if as_json:
            typer.echo(json.dumps([c.to_dict(json=True) for c in found], indent=2))
            _print_auth(wire, public_key, at, as_json=True)
            return
        rows = [(str(c.frame), c.captured_at.isoformat() if c.captured_at else "", c.transport, m)
                for c in found for m in _flat(c.message)]
    else:
        from remoteid.codec import decode_hex, decode_rows_raw

        decoded = [decode_hex(h) for h in messages]
        wire = decode_rows_raw([bytes.fromhex(h.replace(" ", "")) for h in messages])
        if as_json:
            typer.echo(json.dumps([m.to_dict(json=True) for m in decoded], indent=2))
            _print_auth(wire, public_key, at, as_json=True)
            return
        rows = [(str(i), "", "", m) for i, d in enumerate(decoded, 1) for m in _flat(d)]
    from rich.table import Table

    from authn.cli.output import print_table
    from core.textsafe import cell

    t = Table(title=f"{len(rows)} Remote ID messages{title}")
    for col in ("#", "captured", "transport", "type", "v"):
        t.add_column(col, no_wrap=True)  # identifiers and times: never split
    t.add_column("fields", overflow="fold")
    for frame, ts, transport, m in rows:  # the fields are broadcast text: escaped, never markup
        t.add_row(frame, ts, cell(transport), cell(m.type), str(m.protocol_version), cell(_summary(m)))
    print_table(t)
    _print_auth(wire, public_key, at, as_json=False)


def _format_of(path: Path) -> str:
    """'pcap' or 'pcapng' by the file's magic number (`remoteid.capture.capture_format`)."""
    from remoteid.capture import capture_format

    try:
        with open(path, "rb") as f:
            return capture_format(f.read(4)) or "unknown format"
    except OSError:
        return "unreadable"


def _capture_given_as_message(arg: str) -> Optional[Path]:
    """The path of a pcap/pcapng file given where hex messages go (it is decoded as with
    --pcap); a file of any other kind is bad input that says what it is, not 'not hex'."""
    from remoteid.errors import RemoteIdError

    path = Path(arg)
    if not path.is_file():
        return None
    if _format_of(path) in ("pcap", "pcapng"):
        return path
    raise RemoteIdError(f"{arg} is a file, but not a pcap/pcapng capture (unknown magic number); "
                        "give messages as hex, or a capture: authn rid decode --pcap FILE")


def _print_auth(wire: list, public_key: Optional[str], at: Optional[str], as_json: bool) -> None:
    """The DRIP authentication of the decoded messages, when they carry authentication pages."""
    from remoteid import AuthPage, AuthPage0

    messages = [w[0] if isinstance(w, tuple) else w for w in wire]
    if not any(isinstance(m, (AuthPage0, AuthPage)) for m in messages):
        if public_key is not None:
            typer.echo("no authentication pages to verify", err=True)
        return
    from datetime import datetime, timezone

    from core.parsing import parse_iso_time
    from remoteid.drip import det_matches_key, det_to_text, parse_sam, reassemble, valid_time_text, verify

    when = datetime.now(timezone.utc) if at is None else parse_iso_time(at, "--at")
    lines = []
    for msg in reassemble(messages):
        if msg.data is None:
            lines.append(f"auth type {msg.auth_type}: malformed ({msg.reason})")
            continue
        fec = ""
        if msg.fec:
            fec = ", FEC page" + (f" (page {msg.rebuilt} rebuilt from it)" if msg.rebuilt is not None else "")
        try:
            sam = parse_sam(msg.data)
            lines.append(f"auth type {msg.auth_type}: DRIP {sam.name}{fec}, valid {valid_time_text(sam.vnb)} to "
                         f"{valid_time_text(sam.vna)}, DET {det_to_text(sam.det)}")
        except ValueError as exc:
            lines.append(f"auth type {msg.auth_type}: {' '.join(str(exc).split())}")
    result = None
    if public_key is not None:
        from authn.uakeys import read_public_key_arg

        key = read_public_key_arg(public_key)
        result = verify(wire, lambda det: key if det_matches_key(det, key) else None, when)
    if as_json:
        typer.echo(json.dumps({"authentication": lines, "verification": result.to_dict() if result else None},
                              indent=2))
        return
    from core.textsafe import printable

    for line in lines:
        typer.echo(printable(line))
    if result is not None:
        typer.echo(f"verification: {result.status}" + (f" ({result.reason})" if result.reason else "")
                   + (f"; {', '.join(result.sam_types)} covering messages {list(result.covered)}"
                      if result.status == "valid" else ""))


def _flat(msg) -> list:
    return list(msg.messages) if msg.type == "message_pack" else [msg]
