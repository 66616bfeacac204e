"""Text from outside, parsed once for every layer: ISO 8601 times and pydantic errors.

A leaf module (standard library and pydantic types only), so the radar, registry and
decision layers share one reading of a date and one way of turning a validation error
into the one-line message the CLI prints.
"""

from __future__ import annotations

from datetime import datetime, timezone
from typing import Any

from authn.errors import BadInput

__all__ = ["parse_iso_time", "first_error"]


def parse_iso_time(text: str, what: str, *, error: type[BadInput] = BadInput,
                   naive_is_utc: bool = True) -> datetime:
    """ISO 8601 (a trailing `Z` allowed) as an aware datetime. Without an offset the time is
    UTC when `naive_is_utc`, else refused. `what` names the field in the one-line error."""
    try:
        when = datetime.fromisoformat(text.strip().replace("Z", "+00:00"))
    except (ValueError, AttributeError):
        raise error(f"{what}: {text!r} is not an ISO 8601 date/time") from None
    if when.tzinfo is None or when.utcoffset() is None:
        if not naive_is_utc:
            raise error(f"{what}: needs a UTC offset: {text!r}")
        when = when.replace(tzinfo=timezone.utc)
    return when


def first_error(exc: Any) -> tuple[str, str, Any]:
    """The first error of a pydantic ValidationError: (dotted location, message, input).
    The location is '' for a model-level check; pydantic's "Value error, " prefix is dropped."""
    err = exc.errors()[0]
    loc = ".".join(str(p) for p in err["loc"])
    return loc, str(err["msg"]).removeprefix("Value error, "), err.get("input")
