"""UAS IDs read one way: the four F3411 ID types (Basic ID types 1-4) and their normal forms.

Every entry point that takes an identity (`authn check --serial`, `--claims`, `authn register`,
the registry import, the service, a Remote ID broadcast) normalises it here, so a serial written
in lower case is the registered one and a malformed one is bad input (exit 2) wherever it comes in.
"""

from __future__ import annotations

import re
import uuid

from core.errors import BadInput

__all__ = ["CTA_ALPHABET", "F3411_ID_TYPE", "ID_TYPES", "SerialError", "as_heard", "normalise", "validate_cta2063"]

#: ANSI/CTA-2063-A character set: digits and capitals without I and O.
CTA_ALPHABET = "0123456789ABCDEFGHJKLMNPQRSTUVWXYZ"
LENGTH_CHARS = "123456789ABCDEF"
ID_TYPES = ("serial", "caa_registration", "utm_uuid", "specific_session")
#: F3411 Basic ID "ID type" code of each registry id_type.
F3411_ID_TYPE = {"serial": 1, "caa_registration": 2, "utm_uuid": 3, "specific_session": 4}
#: an ID of no stated type is read as the first of these it is valid as
_UNTYPED_ORDER = ("serial", "utm_uuid", "specific_session", "caa_registration")

#: a civil aviation authority's registration: letters, digits, '-' and '.', at least one digit
_CAA = re.compile(r"^(?=.*[0-9])[A-Z0-9][A-Z0-9.\-]{0,19}$")
_HEX = re.compile(r"^(?:[0-9A-F]{2}){1,20}$")


class SerialError(BadInput):
    """A UAS ID that does not meet the rules of its ID type (exit 2)."""


def validate_cta2063(serial: str) -> str:
    """ANSI/CTA-2063-A: 4-char manufacturer code, 1 length char (1-F), that many chars."""
    s = serial.strip().upper()
    if len(s) < 6:
        raise SerialError(f"serial {serial!r}: too short for ANSI/CTA-2063-A (at least 6 characters)")
    bad = sorted({c for c in s if c not in CTA_ALPHABET})
    if bad:
        raise SerialError(
            f"serial {serial!r}: character(s) {''.join(bad)!r} not allowed "
            "(ANSI/CTA-2063-A uses 0-9 and A-Z without I and O)")
    if s[4] not in LENGTH_CHARS:
        raise SerialError(f"serial {serial!r}: length character {s[4]!r} must be 1-9 or A-F")
    want = LENGTH_CHARS.index(s[4]) + 1
    if len(s) - 5 != want:
        raise SerialError(
            f"serial {serial!r}: length character {s[4]!r} announces {want} characters "
            f"after the manufacturer code, found {len(s) - 5}")
    return s


def _typed(value: str, id_type: str) -> str:
    """The normal form of `value` as an ID of `id_type`, or SerialError."""
    if id_type == "serial":
        return validate_cta2063(value)
    v = value.strip()
    if id_type == "caa_registration":
        if not _CAA.match(v.upper()):
            raise SerialError(f"CAA registration {value!r}: 1-20 characters A-Z, 0-9, '-' or '.', "
                              "at least one digit")
        return v.upper()
    if id_type == "utm_uuid":
        try:
            return str(uuid.UUID(v))
        except ValueError:
            raise SerialError(f"UTM UUID {value!r}: not a UUID") from None
    if id_type == "specific_session":
        h = v.upper().removeprefix("0X")
        if not _HEX.match(h) or h[:2] == "00":
            raise SerialError(
                f"specific session ID {value!r}: 1-20 bytes as hex, first byte (session type) 01-FF")
        return h
    raise SerialError(f"unknown ID type {id_type!r} (one of {', '.join(ID_TYPES)})")


def normalise(value: str, id_type: str | None = None) -> str:
    """The normal form of a UAS ID (CTA-2063-A serials and CAA registrations in capitals, UUIDs
    in lower case, session IDs as hex without 0x), or SerialError. Without `id_type` (a claim
    names no type) the ID is read as the first type it is valid as: serial, UTM UUID, session
    ID, CAA registration."""
    if id_type is not None:
        return _typed(value, id_type)
    for kind in _UNTYPED_ORDER:
        try:
            return _typed(value, kind)
        except SerialError:
            continue
    raise SerialError(f"{value!r} is not a UAS ID: not an ANSI/CTA-2063-A serial (e.g. 1581F5FJD12345678901), "
                      "a CAA registration, a UTM UUID or a session ID")


def as_heard(value: str) -> str:
    """A broadcast ID in its normal form where it has one, else as sent (stripped): what a drone
    broadcasts is evidence, so a malformed ID stays as heard (and is unregistered)."""
    try:
        return normalise(value)
    except SerialError:
        return value.strip()
