"""Estimator accuracy on a site's own recordings against independent truth (`authn features score`,
docs/estimators.md).

No simulator is anyone's radar. A site (or a researcher) with recordings whose rotor rate, body
velocity or rotor count it measured some other way (a tachometer, the whole recording's spectrum,
a hover held by GPS) scores today's estimators on them with the same rule as the simulated
real-radar conditions (`lab.accuracy.score`): |v - truth| < 1 m/s, the mechanical rotor rate within
3 %, rotors seen within +-1, and how often the rate read is twice or half the truth.

The truth is a CSV file, one row per recording or per directory of dwells (what `authn import`
writes for one long capture: every dwell of it shares the row's truth):

    file,rotor_rate_hz,radial_velocity_mps,rotors,note
    hover_3300MHz/,161.5,0,4,8 blades tagged
    idle_3350MHz.h5,66.2,0,,

`file` is relative to the CSV's folder (or absolute); an empty cell is not known and not scored.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from core.errors import BadInput
from lab.accuracy import Estimate, Scores, Truth, feature_estimate, score

if TYPE_CHECKING:
    from signatures.recording import Recording

__all__ = ["TRUTH_COLUMNS", "DwellScore", "TruthRow", "as_json", "read_truth", "score_recordings"]

#: The truth file's columns: `file` and at least one quantity are required.
TRUTH_COLUMNS = ("file", "rotor_rate_hz", "radial_velocity_mps", "rotors", "note")
#: Plausible spans of the truth (a typo such as a rate in rpm is refused, not scored).
RATE_SPAN_HZ = (1.0, 2000.0)
SPEED_LIMIT_MPS = 200.0
ROTORS_SPAN = (1, 32)


@dataclass(frozen=True)
class TruthRow:
    """One row of the truth file: the recordings it names and what is known of them."""

    name: str  # the `file` cell as written
    files: tuple[Path, ...]
    truth: Truth


@dataclass(frozen=True)
class DwellScore:
    """One dwell's estimates beside its row's truth."""

    file: str
    row: str
    detected: bool
    rotor_rate_hz: float
    radial_velocity_mps: float
    rotors_seen: float


def _number(cell: str, column: str, line: int, path: Path) -> float | None:
    if not cell.strip():
        return None
    try:
        value = float(cell)
    except ValueError:
        raise BadInput(f"{path}:{line}: {column} {cell.strip()!r} is not a number") from None
    if not math.isfinite(value):
        raise BadInput(f"{path}:{line}: {column} {cell.strip()!r} is not a finite number")
    return value


def _truth(row: dict[str, str], line: int, path: Path) -> Truth:
    rate = _number(row.get("rotor_rate_hz") or "", "rotor_rate_hz", line, path)
    speed = _number(row.get("radial_velocity_mps") or "", "radial_velocity_mps", line, path)
    rotors = _number(row.get("rotors") or "", "rotors", line, path)
    if rate is not None and not RATE_SPAN_HZ[0] <= rate <= RATE_SPAN_HZ[1]:
        raise BadInput(f"{path}:{line}: rotor_rate_hz {rate:g} is outside {RATE_SPAN_HZ[0]:g}-{RATE_SPAN_HZ[1]:g} Hz "
                       "(the mechanical rate in turns per second)")
    if speed is not None and abs(speed) > SPEED_LIMIT_MPS:
        raise BadInput(f"{path}:{line}: radial_velocity_mps {speed:g} exceeds +-{SPEED_LIMIT_MPS:g} m/s")
    if rotors is not None and (rotors != int(rotors) or not ROTORS_SPAN[0] <= rotors <= ROTORS_SPAN[1]):
        raise BadInput(f"{path}:{line}: rotors {rotors:g} is not a whole number in {ROTORS_SPAN[0]}-{ROTORS_SPAN[1]}")
    if rate is None and speed is None and rotors is None:
        raise BadInput(f"{path}:{line}: no truth to score (rotor_rate_hz, radial_velocity_mps and rotors are empty)")
    return Truth(rate, speed, None if rotors is None else int(rotors))


def _files(name: str, line: int, path: Path) -> tuple[Path, ...]:
    from signatures.recording import recordings_in

    target = Path(name.strip())
    target = target if target.is_absolute() else path.parent / target
    if target.is_dir():
        found = recordings_in(target)
        if not found:
            raise BadInput(f"{path}:{line}: {target}: no .h5/.hdf5/.npz recordings in this directory")
        return tuple(found)
    if not target.is_file():
        raise BadInput(f"{path}:{line}: {target}: no such file or directory")
    return (target,)


def read_truth(path: Path) -> list[TruthRow]:
    """The rows of a truth CSV (module docstring), every named recording found; bad input (exit 2,
    one line naming the file and line) otherwise."""
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise BadInput(f"{path}: cannot read the truth file ({type(exc).__name__})") from None
    reader = csv.DictReader(text.splitlines())
    header = [c.strip() for c in reader.fieldnames or []]
    unknown = [c for c in header if c not in TRUTH_COLUMNS]
    if unknown or "file" not in header:
        raise BadInput(f"{path}: columns {', '.join(TRUTH_COLUMNS)} (file required); got {', '.join(header) or 'none'}")
    reader.fieldnames = header
    rows = []
    for line, row in enumerate(reader, start=2):
        if None in row:  # more cells than the header has columns
            raise BadInput(f"{path}:{line}: more cells than the header's {len(header)} columns")
        name = (row.get("file") or "").strip()
        if not name:
            raise BadInput(f"{path}:{line}: the file cell is empty")
        rows.append(TruthRow(name, _files(name, line, path), _truth(row, line, path)))
    if not rows:
        raise BadInput(f"{path}: no rows: one per recording (or directory of dwells) to score")
    return rows


def score_recordings(rows: list[TruthRow], estimate: Callable[[Recording], Estimate] = feature_estimate,
                     advance: Callable[[], None] = lambda: None) -> tuple[list[tuple[str, Scores]], list[DwellScore]]:
    """Each row's scores and every dwell's estimates, then the scores of all rows together
    (labelled "all"). Every recording is read as `authn check` reads it (a file it refuses is bad
    input naming the file)."""
    from signatures.recording import read_recording

    per_row: list[tuple[str, Scores]] = []
    everything: list[tuple[Estimate, Truth]] = []
    dwells: list[DwellScore] = []
    for r in rows:
        pairs = []
        for f in r.files:
            e = estimate(read_recording(f))
            pairs.append((e, r.truth))
            dwells.append(DwellScore(str(f), r.name, e.detected, e.rotor_rate_hz, e.radial_velocity_mps,
                                     e.rotors_seen))
            advance()
        per_row.append((r.name, score(pairs)))
        everything += pairs
    if len(rows) > 1:
        per_row.append(("all", score(everything)))
    return per_row, dwells


def as_json(per_row: list[tuple[str, Scores]], dwells: list[DwellScore]) -> dict[str, object]:
    """The JSON object `authn features score --json` prints (a count not known, NaN, is null)."""
    def plain(doc: dict[str, object]) -> dict[str, object]:
        return {k: None if isinstance(v, float) and math.isnan(v) else v for k, v in doc.items()}

    return {"rows": [{"file": name, **asdict(s)} for name, s in per_row], "dwells": [plain(asdict(d)) for d in dwells]}
