"""Validation of the four F3411 UAS ID types (Basic ID types 1-4): `core.uasid`'s rules.

A registry that accepts malformed serials would never match a broadcast, so every ID is
normalised (`core.uasid.normalise`) before it is stored, as every other entry point does.
"""

from __future__ import annotations

from core import uasid
from registry.errors import RegistryError

__all__ = ["SerialError", "validate_cta2063", "validate_uas_id"]


class SerialError(RegistryError, uasid.SerialError):
    """A UAS ID that does not meet the rules of its ID type, as the registry reports it."""


def validate_uas_id(value: str, id_type: str) -> str:
    """Normalised UAS ID for its type (`core.uasid.normalise`), or SerialError (exit 2)."""
    try:
        return uasid.normalise(value, id_type)
    except uasid.SerialError as exc:
        raise SerialError(str(exc)) from None


def validate_cta2063(serial: str) -> str:
    """An ANSI/CTA-2063-A serial in its normal form, or SerialError."""
    return validate_uas_id(serial, "serial")
