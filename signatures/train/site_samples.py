"""The recordings a site enrols, as enrolment reads them: the labels CSV (untrusted: its paths may
not climb out of its folder), each recording's sample (`SiteSample`: feature vector, physics, label)
and the samples a bundle keeps (`site.npz`) for `models enrol --add`."""

from __future__ import annotations

import csv
import io
import math
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from signatures.errors import SignaturesError

#: Fewest recordings per enrolled model: below this a cross-validated error means nothing.
MIN_RECORDINGS = 5
MAX_LABEL_ROWS = 100_000


MAX_LABEL_BYTES = 8 << 20
_NAME = re.compile(r"[a-z0-9][a-z0-9._-]{0,63}")


class EnrolError(SignaturesError):
    """Enrolment input that cannot be used (exit 2, one line)."""


class LabelRow(BaseModel):
    """One row of LABELS.csv: a recording (relative to the CSV's folder) and its registered model."""

    model_config = ConfigDict(extra="forbid", str_strip_whitespace=True)

    file: str = Field(min_length=1, max_length=4096)
    model: str = Field(pattern=r"^[a-z0-9][a-z0-9_-]{0,31}$")


def read_labels(path: Path) -> list[tuple[Path, str]]:
    """(recording path, model slug) of each row of an untrusted `file,model` CSV. Paths are
    relative to the CSV's folder and may not climb out of it ('..'); a duplicate, a bad header or a bad row
    is an EnrolError naming its line."""
    try:
        if path.stat().st_size > MAX_LABEL_BYTES:
            raise EnrolError(f"{path}: larger than {MAX_LABEL_BYTES >> 20} MiB")
        text = path.read_bytes().decode("utf-8-sig")
    except OSError as exc:
        raise EnrolError(f"{path}: cannot read ({exc.strerror})") from None
    except UnicodeDecodeError:
        raise EnrolError(f"{path}: not UTF-8 text") from None
    rows = list(csv.reader(io.StringIO(text)))
    if not rows or [c.strip().lower() for c in rows[0]] != ["file", "model"]:
        raise EnrolError(f"{path}: the header must be exactly 'file,model'")
    if len(rows) - 1 > MAX_LABEL_ROWS:
        raise EnrolError(f"{path}: more than {MAX_LABEL_ROWS} rows")
    root = Path(os.path.normpath(path.parent.absolute()))
    out: list[tuple[Path, str]] = []
    seen: set[Path] = set()
    for line, cells in enumerate(rows[1:], start=2):
        if not cells or all(not c.strip() for c in cells):
            continue
        if len(cells) != 2:
            raise EnrolError(f"{path}:{line}: expected 2 columns (file,model), got {len(cells)}")
        try:
            row = LabelRow(file=cells[0], model=cells[1])
        except ValidationError as exc:
            err = exc.errors()[0]
            raise EnrolError(f"{path}:{line}: {err['loc'][0]}: {err['msg']}") from None
        rel = Path(row.file)
        if rel.is_absolute() or "\x00" in row.file:
            raise EnrolError(f"{path}:{line}: file must be relative to the CSV's folder")
        lexical = Path(os.path.normpath(root / rel))  # '..' may not climb out; a symlink inside may point out
        target = lexical.resolve()
        if not lexical.is_relative_to(root):
            raise EnrolError(f"{path}:{line}: file {row.file!r} is outside the CSV's folder")
        if target in seen:
            raise EnrolError(f"{path}:{line}: file {row.file!r} is labelled twice")
        if not target.is_file():
            raise EnrolError(f"{path}:{line}: file {row.file!r} does not exist")
        seen.add(target)
        out.append((target, row.model))
    if not out:
        raise EnrolError(f"{path}: no labelled recordings")
    return out


def bundle_name_ok(name: str) -> bool:
    """A site bundle name: lower-case letters, digits, '.', '_', '-', at most 64, not a keyword."""
    from signatures.radar import PRESETS

    return bool(_NAME.fullmatch(name)) and name not in PRESETS and name != "shipped"


@dataclass(frozen=True)
class SiteSample:
    """One enrolment recording as the bundle keeps it: its feature vector, what 1:1 verification
    reads beside it (`physics`), its label and where it came from."""

    name: str
    sha256: str
    model: str
    features: np.ndarray  # the full feature vector (signatures.features.FEATURE_NAMES order)
    physics: dict[str, float]
    detected: bool


def previous_samples(folder: Path) -> list[SiteSample]:
    """The site samples an enrolment bundle keeps (`site.npz`), for `--add`."""
    with np.load(folder / "site.npz", allow_pickle=False) as z:
        names, digests, models = z["names"], z["sha256"], z["models"]
        X, P, pnames, det = z["X"], z["physics"], [str(n) for n in z["physics_names"]], z["detected"]
    return [SiteSample(str(n), str(d), str(m), X[i], {k: float(P[i, j]) for j, k in enumerate(pnames)
                                                       if math.isfinite(P[i, j])}, bool(det[i]))
            for i, (n, d, m) in enumerate(zip(names, digests, models))]


def site_arrays(samples: Sequence[SiteSample]) -> dict[str, np.ndarray]:
    pnames = sorted({k for s in samples for k in s.physics})
    P = np.full((len(samples), len(pnames)), np.nan)
    for i, s in enumerate(samples):
        for j, k in enumerate(pnames):
            if k in s.physics:
                P[i, j] = s.physics[k]
    return {"names": np.array([s.name for s in samples]), "sha256": np.array([s.sha256 for s in samples]),
            "models": np.array([s.model for s in samples]), "X": np.stack([s.features for s in samples]),
            "physics": P, "physics_names": np.array(pnames, dtype=str),
            "detected": np.array([s.detected for s in samples])}

