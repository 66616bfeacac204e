"""core.checked: declared constraints hold on construction, on `from_dict` and on `replace`;
`to_dict` and `from_dict` round-trip; every refusal is an `Invalid` naming its field."""

from __future__ import annotations

import math
from dataclasses import FrozenInstanceError, dataclass
from datetime import datetime, timedelta, timezone

import pytest
from hypothesis import given
from hypothesis import strategies as st

from core.checked import Checked, Invalid, choice, data, integer, moment, number, rule, text

EPOCH = datetime(2019, 1, 1, tzinfo=timezone.utc)


@dataclass(frozen=True, kw_only=True)
class Probe(Checked):
    nibble: int = integer(0, ge=0, le=15)
    rate: float = number(ge=0.0, lt=100.0, finite=True)
    name: str = text("", max_length=8, pattern=r"^[a-z]*$")
    blob: bytes = data(b"", max_length=4)
    kind: str = choice("a", "b", default="a")
    when: datetime | None = moment(None, ge=EPOCH, optional=True)

    def _check(self) -> None:
        if self.kind == "b" and not self.name:
            raise ValueError("kind b needs a name")


@given(st.integers(0, 15), st.floats(0.0, 100.0, exclude_max=True), st.text("abc", max_size=8),
       st.binary(max_size=4), st.sampled_from(["a", "b"]))
def test_values_inside_the_constraints_round_trip(nibble, rate, name, blob, kind) -> None:
    if kind == "b" and not name:
        name = "x"
    p = Probe(nibble=nibble, rate=rate, name=name, blob=blob, kind=kind, when=EPOCH)
    assert Probe.from_dict(p.to_dict()) == p
    assert p.to_dict(json=True)["blob"] == blob.hex() and p.to_dict(json=True)["when"] == "2019-01-01T00:00:00Z"


@given(st.one_of(st.integers(max_value=-1), st.integers(min_value=16)))
def test_an_integer_outside_its_bounds_is_refused_naming_the_field(n) -> None:
    with pytest.raises(Invalid) as e:
        Probe(nibble=n, rate=1.0)
    assert e.value.loc == "nibble" and "than or equal to" in e.value.msg and e.value.value == n


@pytest.mark.parametrize("bad", [math.nan, math.inf, -1.0, 100.0, "fast", None, [1.0]])
def test_a_bad_number_is_refused(bad) -> None:
    with pytest.raises(Invalid, match=r"^rate: Input should be"):
        Probe(rate=bad)


def test_lax_coercion_as_a_validator_would() -> None:
    p = Probe(nibble=3.0, rate="2.5", name=b"ab", blob=bytearray(b"\x01"))
    assert (p.nibble, p.rate, p.name, p.blob) == (3, 2.5, "ab", b"\x01")
    assert type(p.nibble) is int and type(p.blob) is bytes
    with pytest.raises(Invalid, match="fractional part"):
        Probe(nibble=1.5, rate=1.0)


def test_text_data_choice_and_moment_constraints() -> None:
    for fields, loc in (({"name": "ABC"}, "name"), ({"name": "abcdefghi"}, "name"), ({"name": "ab\n"}, "name"),
                        ({"blob": b"12345"}, "blob"), ({"kind": "c"}, "kind"),
                        ({"when": datetime(2020, 1, 1)}, "when"), ({"when": EPOCH - timedelta(seconds=1)}, "when")):
        with pytest.raises(Invalid) as e:
            Probe(rate=1.0, **fields)
        assert e.value.loc == loc, fields


def test_rules_across_fields_and_replace_are_checked() -> None:
    with pytest.raises(Invalid, match="^kind b needs a name$"):
        Probe(rate=1.0, kind="b")
    p = Probe(rate=1.0)
    with pytest.raises(Invalid, match="^nibble:"):
        p.replace(nibble=99)
    assert p.replace(nibble=9).nibble == 9
    with pytest.raises(FrozenInstanceError):
        p.nibble = 2  # type: ignore[misc]


def test_from_dict_refuses_unknown_and_missing_fields_and_non_objects() -> None:
    with pytest.raises(Invalid, match="^rate: Field required$"):
        Probe.from_dict({})
    with pytest.raises(Invalid, match="^extra: Extra inputs are not permitted$"):
        Probe.from_dict({"rate": 1.0, "extra": 1})
    with pytest.raises(Invalid, match="valid dictionary"):
        Probe.from_dict([("rate", 1.0)])


def test_from_dict_checks_each_field_once_and_still_runs_the_rules_across_fields() -> None:
    seen: list[object] = []

    def counted(value: object) -> str:
        seen.append(value)
        return str(value).strip()

    @dataclass(frozen=True, kw_only=True)
    class Counted(Checked):
        name: str = rule(counted)
        note: str | None = rule(counted, None, optional=True)

        def _check(self) -> None:
            if self.name == "no":
                raise ValueError("not that name")

    made = Counted.from_dict({"name": " x "})
    assert made == Counted(name="x") and seen == [" x ", "x"]  # from_dict once, the constructor once
    with pytest.raises(Invalid, match="not that name"):
        Counted.from_dict({"name": "no"})
