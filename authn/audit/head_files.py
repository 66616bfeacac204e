"""The files that keep signed tree heads outside the database: the STH log (JSON lines, one head
per line naming its database; `--sth-log`, else $AUTHN_AUDIT_STH_LOG, else beside the log key)
and the latest-head file beside it (one head per database, replaced atomically)."""

from __future__ import annotations

import hashlib
import os
from collections.abc import Iterator
from pathlib import Path

from core.errors import AuthnError, SystemFault
from core.parsing import loads_json
from core.settings import current
from authn.audit.logkey import key_path
from authn.audit.tree_head import SignedTreeHead, canonical_json

def sth_log_path(explicit: str | Path | None = None, key: str | Path | None = None) -> Path:
    """Where automatic STHs are appended (JSON lines): $AUTHN_AUDIT_STH_LOG, else beside the key."""
    explicit = explicit or current().audit_sth_log
    if explicit:
        return Path(explicit).expanduser()
    return key_path(key).parent / "audit-sth.jsonl"


def read_sth_log(path: Path) -> list[tuple[str | None, SignedTreeHead]]:
    """Every well-formed STH line of an external STH file (a missing file is an empty list)."""
    return scan_sth_log(path)[0]


def scan_sth_log(path: Path) -> tuple[list[tuple[str | None, SignedTreeHead]], list[int]]:
    """The well-formed STH lines of an STH file, and the numbers of the non-blank lines that
    are not one (damage `verify` reports). Lines carry the STH fields plus "db" (which
    database they vouch for). A missing file has neither."""
    try:
        lines = path.read_bytes().splitlines()
    except FileNotFoundError:
        return [], []
    except OSError as exc:
        raise SystemFault(f"{path}: cannot read the STH log ({exc.strerror})") from None
    out: list[tuple[str | None, SignedTreeHead]] = []
    bad: list[int] = []
    for number, line in enumerate(lines, start=1):
        if not line.strip():
            continue
        try:
            doc = loads_json(line.decode("utf-8"))
            out.append((doc.get("db"), SignedTreeHead.from_dict({k: v for k, v in doc.items() if k != "db"})))
        except (UnicodeDecodeError, ValueError, AuthnError, AttributeError):
            bad.append(number)
    return out, bad


def lines_from_end(path: Path, what: str) -> Iterator[bytes]:
    """The lines of a file, last first, read backwards a block at a time: the newest head of
    an append-only file that grows with the log, without reading all of it (none: no file)."""
    try:
        fh = open(path, "rb")
    except FileNotFoundError:
        return
    except OSError as exc:
        raise SystemFault(f"{path}: cannot read the {what} ({exc.strerror})") from None
    with fh:
        end = fh.seek(0, os.SEEK_END)
        tail = b""
        while end > 0:
            start = max(0, end - (1 << 16))
            fh.seek(start)
            block = fh.read(end - start) + tail
            lines = block.split(b"\n")
            tail = lines.pop(0) if start > 0 else b""  # maybe cut: joined with the next block
            yield from reversed(lines)
            end = start


def newest_in_sth_log(path: Path, db_label: str) -> SignedTreeHead | None:
    """The last well-formed line for `db_label` (the writer asks on every append)."""
    for line in lines_from_end(path, "STH log"):
        if db_label.encode() not in line:
            continue
        try:
            doc = loads_json(line.decode("utf-8"))
            if doc.get("db") == db_label:
                return SignedTreeHead.from_dict({k: v for k, v in doc.items() if k != "db"})
        except (UnicodeDecodeError, ValueError, AuthnError, AttributeError):
            continue
    return None


def append_sth_log(path: Path, sth: SignedTreeHead, db_label: str) -> None:
    """One JSON line, one write(2) on an O_APPEND descriptor (concurrent writers do not interleave)."""
    line = (canonical_json({**sth.to_dict(), "db": db_label}) + "\n").encode()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
        try:
            os.write(fd, line)
        finally:
            os.close(fd)
    except OSError as exc:
        raise SystemFault(f"{path}: cannot append to the STH log ({exc.strerror})") from None


def latest_head_path(sth_log: Path, db_label: str) -> Path:
    """The newest signed head of one database: a small file beside the STH log (one per
    database, named by a digest of its label, so several databases can share the folder)."""
    return sth_log.with_name(f"{sth_log.stem}-latest-{hashlib.sha256(db_label.encode()).hexdigest()[:16]}.json")


def read_latest_head(path: Path) -> SignedTreeHead | None:
    """The head in a latest-head file (None when there is none yet); a file that does not
    parse is a system fault: someone damaged the log's external state."""
    try:
        text = path.read_bytes()
    except FileNotFoundError:
        return None
    except OSError as exc:
        raise SystemFault(f"{path}: cannot read the latest signed head ({exc.strerror})") from None
    try:
        doc = loads_json(text.decode("utf-8"))
        return SignedTreeHead.from_dict({k: v for k, v in doc.items() if k != "db"})
    except (UnicodeDecodeError, ValueError, AuthnError, AttributeError):
        raise SystemFault(f"{path}: the latest signed head is not an authn-sth/1 document") from None


def write_latest_head(path: Path, sth: SignedTreeHead, db_label: str) -> None:
    """Replace the latest-head file with `sth` unless it already holds a larger tree: an
    exclusive flock orders concurrent writers, and write-then-rename keeps the file whole."""
    import fcntl

    data = (canonical_json({**sth.to_dict(), "db": db_label}) + "\n").encode()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        lock = os.open(str(path) + ".lock", os.O_CREAT | os.O_RDWR, 0o644)
        try:
            fcntl.flock(lock, fcntl.LOCK_EX)
            current = read_latest_head(path)
            if current is not None and current.tree_size > sth.tree_size:
                return
            tmp = path.with_name(f"{path.name}.{os.getpid()}.tmp")
            tmp.write_bytes(data)
            os.replace(tmp, path)
        finally:
            os.close(lock)
    except OSError as exc:
        raise SystemFault(f"{path}: cannot write the latest signed head ({exc.strerror})") from None

