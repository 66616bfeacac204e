"""Plain frozen dataclasses with declared field constraints, checked on construction.

The typed values a check builds (Remote ID messages, the radar configuration and site, UAV
profiles) are `Checked` dataclasses: each field declares its constraint (`number`, `integer`,
`text`, `data`, `choice`, `moment`, or `rule` with a check of its own) and `__post_init__`
enforces it, coercing as a lax validator would (an int for a float field, an integral float or
numeric string for an int field); a class's rules across fields go in `_check`. A violation raises `Invalid`, a
ValueError carrying the field (`loc`), the reason (`msg`, worded as pydantic words it) and the
input. Standard library only: importing it costs nothing, unlike pydantic (~90 ms).

`from_dict` reads an external document (a JSON object): unknown keys and missing required
fields are refused. `to_dict` writes one back (`json=True`: bytes as hex, datetimes as ISO
8601 with `Z` for UTC, as pydantic's JSON mode does). `replace` is `dataclasses.replace`.
"""

from __future__ import annotations

import dataclasses
import math
import operator
import re
from datetime import datetime
from typing import TYPE_CHECKING, Any, Callable, ClassVar, Self

__all__ = ["Checked", "Invalid", "choice", "data", "integer", "moment", "number", "rule", "text"]

_MISSING = dataclasses.MISSING


class Invalid(ValueError):
    """A value a declared constraint refuses: `loc` names the field ('' for a rule across
    fields), `msg` says why in one line, `value` is the input."""

    def __init__(self, loc: str, msg: str, value: Any = None) -> None:
        super().__init__(f"{loc}: {msg}" if loc else msg)
        self.loc, self.msg, self.value = loc, msg, value


def _show(bound: Any) -> str:
    """A bound as pydantic prints it: 1e12 as 1000000000000, 0.5 as 0.5."""
    if isinstance(bound, float) and bound.is_integer() and abs(bound) < 1e16:
        return str(int(bound))
    if isinstance(bound, datetime):
        return _iso(bound)
    return str(bound)


def _iso(when: datetime) -> str:
    text = when.isoformat()
    return text[:-6] + "Z" if text.endswith("+00:00") else text


def _as_text(value: Any) -> Any:
    """bytes read as UTF-8 text, as a lax validator reads them; anything else unchanged."""
    return value.decode("utf-8", "replace") if isinstance(value, (bytes, bytearray)) else value


def _parse(text: str, kind: type, what: str) -> Any:
    """`kind(text)` or pydantic's words for text that is not a `what` ("a number", "an integer")."""
    try:
        return kind(text.strip())
    except ValueError:
        raise ValueError(f"Input should be a valid {what.split()[1]}, unable to parse string as {what}") from None


def _to_float(value: Any) -> float:
    if isinstance(value, float):
        return value
    value = _as_text(value)
    if isinstance(value, str):
        return _parse(value, float, "a number")
    try:
        return float(value) if isinstance(value, (int, float)) or hasattr(value, "__float__") else _bad_number()
    except (TypeError, OverflowError):
        return _bad_number()


def _bad_number() -> float:
    raise ValueError("Input should be a valid number")


def _to_int(value: Any) -> int:
    if type(value) is int:
        return value
    value = _as_text(value)
    if isinstance(value, str):
        return _parse(value, int, "an integer")
    if isinstance(value, float) or (hasattr(value, "__float__") and not hasattr(value, "__index__")):
        value = float(value)
        if not math.isfinite(value):
            raise ValueError("Input should be a finite number")
        if not value.is_integer():
            raise ValueError("Input should be a valid integer, got a number with a fractional part")
        return int(value)
    try:
        return operator.index(value)  # int, bool, numpy integers
    except TypeError:
        raise ValueError("Input should be a valid integer") from None


def _bounds(value: Any, ge: Any, gt: Any, le: Any, lt: Any, multiple_of: Any) -> None:
    """pydantic's order: multiple_of, le, lt, ge, gt (NaN fails the first bound it meets)."""
    if multiple_of is not None and value % multiple_of:
        raise ValueError(f"Input should be a multiple of {_show(multiple_of)}")
    if le is not None and not value <= le:
        raise ValueError(f"Input should be less than or equal to {_show(le)}")
    if lt is not None and not value < lt:
        raise ValueError(f"Input should be less than {_show(lt)}")
    if ge is not None and not value >= ge:
        raise ValueError(f"Input should be greater than or equal to {_show(ge)}")
    if gt is not None and not value > gt:
        raise ValueError(f"Input should be greater than {_show(gt)}")


def rule(check: Callable[[Any], Any], default: Any = _MISSING, *, optional: bool = False) -> Any:
    """A field that `check` coerces or refuses (ValueError); None passes when `optional`."""
    def checked(value: Any) -> Any:
        return None if optional and value is None else check(value)

    return dataclasses.field(default=default, metadata={"check": checked})


def number(default: Any = _MISSING, *, ge: float | None = None, gt: float | None = None,
           le: float | None = None, lt: float | None = None, finite: bool = False,
           optional: bool = False) -> Any:
    """A float field (ints and numeric strings coerced); `finite` refuses NaN and infinities
    before the bounds are compared."""
    def check(value: Any) -> float:
        x = _to_float(value)
        if finite and not math.isfinite(x):
            raise ValueError("Input should be a finite number")
        _bounds(x, ge, gt, le, lt, None)
        return x

    return rule(check, default, optional=optional)


def integer(default: Any = _MISSING, *, ge: int | None = None, gt: int | None = None, le: int | None = None,
            lt: int | None = None, multiple_of: int | None = None, optional: bool = False) -> Any:
    """An int field (an integral float, a bool or a numeric string coerced)."""
    def check(value: Any) -> int:
        x = _to_int(value)
        _bounds(x, ge, gt, le, lt, multiple_of)
        return x

    return rule(check, default, optional=optional)


def text(default: Any = _MISSING, *, min_length: int | None = None, max_length: int | None = None,
         pattern: str | None = None, optional: bool = False) -> Any:
    """A str field; `pattern` is searched (anchor it as pydantic's patterns are)."""
    # `$` ends the text (as in pydantic's regex engine), not before a trailing newline as in `re`
    compiled = None if pattern is None else re.compile(pattern[:-1] + r"\Z" if pattern.endswith("$") else pattern)

    def check(value: Any) -> str:
        if isinstance(value, (bytes, bytearray)):
            try:
                value = bytes(value).decode("utf-8")
            except UnicodeDecodeError:
                raise ValueError("Input should be a valid string, unable to parse raw data as a unicode "
                                 "string") from None
        if not isinstance(value, str):
            raise ValueError("Input should be a valid string")
        if min_length is not None and len(value) < min_length:
            raise ValueError(f"String should have at least {min_length} character{'s' * (min_length != 1)}")
        if max_length is not None and len(value) > max_length:
            raise ValueError(f"String should have at most {max_length} character{'s' * (max_length != 1)}")
        if compiled is not None and not compiled.search(value):
            raise ValueError(f"String should match pattern '{pattern}'")
        return value

    return rule(check, default, optional=optional)


def data(default: Any = _MISSING, *, min_length: int | None = None, max_length: int | None = None) -> Any:
    """A bytes field (bytearray and memoryview copied to bytes, str encoded as UTF-8)."""
    def check(value: Any) -> bytes:
        if isinstance(value, str):
            value = value.encode("utf-8")
        if not isinstance(value, (bytes, bytearray, memoryview)):
            raise ValueError("Input should be a valid bytes")
        value = bytes(value)
        if min_length is not None and len(value) < min_length:
            raise ValueError(f"Data should have at least {min_length} byte{'s' * (min_length != 1)}")
        if max_length is not None and len(value) > max_length:
            raise ValueError(f"Data should have at most {max_length} byte{'s' * (max_length != 1)}")
        return value

    return rule(check, default, optional=False)


def choice(*values: Any, default: Any = _MISSING) -> Any:
    """One of `values` (a Literal); equal values of another type (1.0 for 1) become the declared one."""
    if len(values) == 1:
        words = repr(values[0])
    else:
        words = ", ".join(repr(v) for v in values[:-1]) + f" or {values[-1]!r}"

    def check(value: Any) -> Any:
        for v in values:
            if value == v and (type(value) is type(v) or not isinstance(v, str) and not isinstance(value, str)):
                return v
        raise ValueError(f"Input should be {words}")

    return rule(check, default, optional=False)


def moment(default: Any = _MISSING, *, ge: datetime | None = None, le: datetime | None = None,
           optional: bool = False) -> Any:
    """An aware datetime field within [ge, le] (a naive one is refused: its UTC time is unknown)."""
    def check(value: Any) -> datetime:
        if not isinstance(value, datetime):
            raise ValueError("Input should be a valid datetime")
        if value.tzinfo is None or value.utcoffset() is None:
            raise ValueError("Input should have timezone info")
        if le is not None and not value <= le:
            raise ValueError(f"Input should be less than or equal to {_show(le)}")
        if ge is not None and not value >= ge:
            raise ValueError(f"Input should be greater than or equal to {_show(ge)}")
        return value

    return rule(check, default, optional=optional)


def _rules(cls: type) -> tuple[tuple[str, Callable[[Any], Any]], ...]:
    """(name, check) of each constrained field, computed once per class."""
    found = cls.__dict__.get("_checked_rules")
    if found is None:
        found = tuple((f.name, f.metadata["check"]) for f in dataclasses.fields(cls) if "check" in f.metadata)
        setattr(cls, "_checked_rules", found)  # noqa: B010 - a class attribute the class does not declare
    return found


def _plain(value: Any, json: bool) -> Any:
    if isinstance(value, Checked):
        return value.to_dict(json=json)
    if isinstance(value, (list, tuple)):
        return [_plain(v, json) for v in value] if json else type(value)(_plain(v, json) for v in value)
    if json and isinstance(value, bytes):
        return value.hex()
    if json and isinstance(value, datetime):
        return _iso(value)
    return value


def _apply(name: str, check: Callable[[Any], Any], value: Any) -> Any:
    """Field `name`'s check of `value`: its coerced value, or Invalid located at the field."""
    try:
        return check(value)
    except Invalid as exc:
        raise Invalid(f"{name}.{exc.loc}" if exc.loc else name, exc.msg, exc.value) from None
    except ValueError as exc:
        raise Invalid(name, str(exc), value) from None


class Checked:
    """Base of a frozen dataclass whose fields declare their constraints (see the module doc).

    Subclasses are `@dataclass(frozen=True, kw_only=True)`; `_check` holds their rules across
    fields and raises `Invalid('', why)` (or a ValueError, which becomes one)."""

    __slots__ = ()
    if TYPE_CHECKING:  # what @dataclass gives every subclass: dataclasses.fields() and replace() take it
        __dataclass_fields__: ClassVar[dict[str, dataclasses.Field[Any]]]

    def __post_init__(self) -> None:
        for name, check in _rules(type(self)):
            value = getattr(self, name)
            new = _apply(name, check, value)
            if new is not value:
                object.__setattr__(self, name, new)
        self._check_across()

    def _check_across(self) -> None:
        try:
            self._check()
        except Invalid:
            raise
        except ValueError as exc:
            raise Invalid("", str(exc)) from None

    def _check(self) -> None:
        """Rules across fields (none by default)."""

    @classmethod
    def from_dict(cls, doc: Any) -> Self:
        """An instance from an external document: a dict with the declared fields, no others.
        The first error is reported as pydantic orders them: fields in declaration order (a
        missing one or a refused value), then unknown keys, then the rules across fields.
        Each field is checked once (here, not again by `__init__`)."""
        if not isinstance(doc, dict):
            raise Invalid("", f"Input should be a valid dictionary or instance of {cls.__name__}", doc)
        values: dict[str, Any] = {}
        for f in dataclasses.fields(cls):
            if f.name in doc:
                value = doc[f.name]
            elif f.default is not _MISSING:
                value = f.default
            elif f.default_factory is not _MISSING:
                value = f.default_factory()
            else:
                raise Invalid(f.name, "Field required", doc)
            check = f.metadata.get("check")
            values[f.name] = _apply(f.name, check, value) if check is not None else value
        extra = next((k for k in doc if k not in values), None)
        if extra is not None:
            raise Invalid(str(extra), "Extra inputs are not permitted", doc[extra])
        made = object.__new__(cls)
        for name, value in values.items():
            object.__setattr__(made, name, value)
        made._check_across()
        return made

    def to_dict(self, *, json: bool = False, exclude: tuple[str, ...] = ()) -> dict[str, Any]:
        """The fields in declaration order (nested Checked values as dicts)."""
        return {f.name: _plain(getattr(self, f.name), json) for f in dataclasses.fields(self)
                if f.name not in exclude}

    def replace(self, **changes: Any) -> Self:
        """A copy with `changes`, checked like a new instance."""
        return dataclasses.replace(self, **changes)
