"""UAV airframe profiles: a profile is its physical parameters, stored as data.

A new airframe is a new JSON entry (or a registry row), never new code: the
simulator and the classifiers read only these numbers.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

from core.checked import Checked, Invalid, integer, number, text
from core.parsing import JsonTooDeep, loads_json
from signatures.errors import SignaturesError

#: Classes the radar knows besides UAV profiles.
NON_UAV_CLASSES = ("bird", "none")
UNKNOWN = "unknown"
#: the package's data files (read as files: importlib.resources costs a cold check ~5 ms to import)
DATA = Path(__file__).with_name("data")


@dataclass(frozen=True, kw_only=True)
class UavProfile(Checked):
    """Physical parameters of a multirotor airframe (checked on construction: `core.checked`)."""

    slug: str = text(pattern=r"^[a-z0-9][a-z0-9_-]{0,31}$")
    name: str = text(min_length=1, max_length=100)
    rotors: int = integer(ge=1, le=16)
    arms: int = integer(ge=1, le=16)
    blades_per_rotor: int = integer(2, ge=1, le=8)
    blade_length_m: float = number(gt=0.01, le=3.0)
    rotor_rate_hz: float = number(gt=1.0, le=500.0)
    propeller_distance_m: float = number(gt=0.05, le=10.0)

    def _check(self) -> None:
        if self.slug in NON_UAV_CLASSES or self.slug == UNKNOWN:
            raise ValueError(f"slug {self.slug!r} is reserved")
        if self.rotors % self.arms and self.arms % self.rotors:
            raise ValueError("rotors must be a multiple of arms (coaxial) or equal to it")

    @property
    def tip_speed_mps(self) -> float:
        """Blade-tip speed 2*pi*f_rot*L."""
        return 2.0 * math.pi * self.rotor_rate_hz * self.blade_length_m

    @property
    def blade_flash_rate_hz(self) -> float:
        """Flashes per second of one rotor: N*f_rot for even N, 2*N*f_rot for odd N."""
        n = self.blades_per_rotor
        return (n if n % 2 == 0 else 2 * n) * self.rotor_rate_hz


def parse_profiles(data: object, source: str) -> dict[str, UavProfile]:
    """Validate a `{"profiles": [...]}` document into profiles keyed by slug."""
    if not isinstance(data, dict) or not isinstance(data.get("profiles"), list):
        raise SignaturesError(f"{source}: expected an object with a 'profiles' list")
    out: dict[str, UavProfile] = {}
    for i, entry in enumerate(data["profiles"]):
        try:
            p = UavProfile.from_dict(entry)
        except Invalid as exc:
            raise SignaturesError(f"{source}: profiles[{i}].{exc.loc or 'profile'}: {exc.msg}") from None
        if p.slug in out:
            raise SignaturesError(f"{source}: duplicate profile slug {p.slug!r}")
        out[p.slug] = p
    return out


def load_profiles(path: str | Path | None = None) -> dict[str, UavProfile]:
    """Shipped profiles (default) or those of a JSON file, keyed by slug."""
    if path is None:
        text = (DATA / "profiles.json").read_text(encoding="utf-8")
        source = "shipped profiles"
    else:
        try:
            text = Path(path).read_text()
        except OSError as exc:
            raise SignaturesError(f"{path}: cannot read profiles ({exc.strerror})") from None
        source = str(path)
    try:
        data = loads_json(text)
    except JsonTooDeep as exc:
        raise SignaturesError(f"{source}: {exc}") from None
    except json.JSONDecodeError as exc:
        raise SignaturesError(f"{source}: not JSON ({exc.msg} at line {exc.lineno})") from None
    return parse_profiles(data, source)


def shipped_profiles() -> dict[str, UavProfile]:
    """The three shipped profiles (signatures/data/profiles.json)."""
    return load_profiles()
