"""Text from outside, parsed once for every layer: ISO 8601 times, JSON documents (with a
nesting limit) and validation errors (`core.checked.Invalid`, pydantic's ValidationError).

A leaf module (standard library only), so the radar, registry and
decision layers share one reading of a date and one way of turning a validation error
into the one-line message the CLI prints.
"""

from __future__ import annotations

import json
import math
from datetime import datetime, timedelta, timezone
from typing import Any

from core.checked import Invalid
from core.errors import BadInput

__all__ = ["parse_iso_time", "in_utc_range", "first_error", "loads_json", "JsonTooDeep", "MAX_JSON_DEPTH",
           "MAX_JSON_INT_DIGITS"]

#: Deepest nesting of arrays and objects a JSON file from outside may have (a registry
#: export is 3 deep, a radar configuration 2): anything deeper is refused as bad input
#: before a recursive reader (json, pydantic, our own walkers) can hit Python's recursion limit.
MAX_JSON_DEPTH = 64

#: Longest integer literal a JSON file from outside may hold: no field needs more than 20 digits,
#: and Python refuses to convert more than 4,300 (a ValueError deep inside the parser).
MAX_JSON_INT_DIGITS = 100

_MIN_SAFE = datetime.min + timedelta(days=1)
_MAX_SAFE = datetime.max - timedelta(days=1)


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
    if not in_utc_range(when):
        raise error(f"{what}: {text!r} is out of range (UTC times from 0001-01-02 to 9999-12-30)")
    return when


def in_utc_range(when: datetime) -> bool:
    """Whether an aware datetime converts to UTC (and every other zone) without overflowing:
    `0001-01-01T00:00:00+23:59` is a valid ISO 8601 text whose UTC instant is before year 1,
    which Python cannot represent. One day of margin at either end keeps a later
    `astimezone` to any offset safe too."""
    try:
        utc = when.astimezone(timezone.utc)
    except OverflowError:
        return False
    return _MIN_SAFE <= utc.replace(tzinfo=None) <= _MAX_SAFE


def first_error(exc: Any) -> tuple[str, str, Any]:
    """The first error of a validation failure, a `core.checked.Invalid` or a pydantic
    ValidationError: (dotted location, message, input). The location is '' for a rule across
    fields; pydantic's "Value error, " prefix is dropped."""
    if isinstance(exc, Invalid):
        return exc.loc, exc.msg, exc.value
    err = exc.errors()[0]
    loc = ".".join(str(p) for p in err["loc"])
    return loc, str(err["msg"]).removeprefix("Value error, "), err.get("input")


class JsonTooDeep(ValueError):
    """A JSON document nested deeper than the limit (a ValueError, like json.JSONDecodeError)."""

    def __init__(self, max_depth: int) -> None:
        super().__init__(f"nesting deeper than {max_depth} levels")
        self.msg = str(self)  # json.JSONDecodeError's attribute, for callers that print it
        self.max_depth = max_depth


def loads_json(text: str | bytes, *, max_depth: int = MAX_JSON_DEPTH) -> Any:
    """`json.loads`, refusing documents nested deeper than `max_depth` arrays/objects with
    JsonTooDeep. json's own parser is recursive: a 100,000-deep array raises RecursionError
    inside it, which is reported the same way; the depth of what did parse is then measured
    without recursion. Syntax errors are json.JSONDecodeError, as from json.loads, and so are
    numbers no field can hold: NaN and Infinity (not JSON), an integer of more than
    MAX_JSON_INT_DIGITS digits, a number beyond a 64-bit float."""
    try:
        doc = json.loads(text, parse_int=lambda s: _int(text, s), parse_float=lambda s: _float(text, s),
                         parse_constant=lambda s: _refuse(text, s, f"{s} is not a JSON number"))
    except RecursionError:
        raise JsonTooDeep(max_depth) from None
    if json_depth(doc, max_depth) > max_depth:
        raise JsonTooDeep(max_depth)
    return doc


def _refuse(text: str | bytes, literal: str, why: str) -> Any:
    """A number the document may not hold, as json's own error at that number's position."""
    doc = text if isinstance(text, str) else text.decode("utf-8", "replace")
    raise json.JSONDecodeError(why, doc, max(doc.find(literal), 0))


def _int(text: str | bytes, literal: str) -> int:
    digits = len(literal.lstrip("-"))
    if digits > MAX_JSON_INT_DIGITS:
        _refuse(text, literal, f"an integer of {digits} digits, more than {MAX_JSON_INT_DIGITS}")
    return int(literal)


def _float(text: str | bytes, literal: str) -> float:
    value = float(literal)
    if not math.isfinite(value):
        _refuse(text, literal, f"{literal[:24]}{'...' if len(literal) > 24 else ''} is beyond a 64-bit float")
    return value


def json_depth(doc: Any, stop_after: int | None = None) -> int:
    """Nesting depth of a parsed JSON value (a scalar 0, `[]` 1, `{"a": [1]}` 2), measured
    with an explicit stack; stops early once deeper than `stop_after`."""
    deepest = 0
    stack: list[tuple[Any, int]] = [(doc, 1)]
    while stack:
        value, depth = stack.pop()
        if not isinstance(value, (dict, list)):
            continue
        deepest = max(deepest, depth)
        if stop_after is not None and deepest > stop_after:
            return deepest
        children = value.values() if isinstance(value, dict) else value
        stack.extend((c, depth + 1) for c in children if isinstance(c, (dict, list)))
    return deepest
