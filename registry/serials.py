"""Validation of the four F3411 UAS ID types (Basic ID types 1-4).

A registry that accepts malformed serials would never match a broadcast, so
every ID is checked and normalised before it is stored.
"""

from __future__ import annotations

import re
import uuid

from registry.errors import RegistryError

#: ANSI/CTA-2063-A character set: digits and capitals without I and O.
CTA_ALPHABET = "0123456789ABCDEFGHJKLMNPQRSTUVWXYZ"
LENGTH_CHARS = "123456789ABCDEF"
ID_TYPES = ("serial", "caa_registration", "utm_uuid", "specific_session")
#: F3411 Basic ID "ID type" code of each registry id_type.
F3411_ID_TYPE = {"serial": 1, "caa_registration": 2, "utm_uuid": 3, "specific_session": 4}

_CAA = re.compile(r"^[A-Z0-9][A-Z0-9.\-]{0,19}$")
_HEX = re.compile(r"^(?:[0-9A-F]{2}){1,20}$")


class SerialError(RegistryError):
    """A UAS ID that does not meet the rules of its ID type."""


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


def validate_uas_id(value: str, id_type: str) -> str:
    """Normalised UAS ID for its type, or SerialError."""
    if id_type == "serial":
        return validate_cta2063(value)
    v = value.strip()
    if id_type == "caa_registration":
        if not _CAA.match(v.upper()):
            raise SerialError(f"CAA registration {value!r}: 1-20 characters A-Z, 0-9, '-' or '.'")
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
