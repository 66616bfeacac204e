"""Which radar target is the claim's: the detection that matches the Remote ID's position and velocity.

A dwell may hold several targets (a second drone, a bird). The claim must be verified against
its own target, never a neighbour's rotors, so before the features run the check associates:

* the radar's targets in the recorded window are listed (`signatures.features.detections`:
  CFAR clusters at least 10 dB over the profile's median, one per `GATE_BINS` of range);
* a target *could match* when its range lies within the claim's range tolerance of the range the
  Remote ID position predicts (`authn.kinematics.residuals`: 2 range bins + the declared
  accuracies; the same tolerance `range-mismatch` applies);
* one such target: the features are gated on it; several: the one nearest the claim in range and
  radial velocity together wins, each residual over its own tolerance
  ((dr / r_tol)^2 + (dv / v_tol)^2: two targets the range cannot tell apart are told apart by
  the declared velocity projected on the line of sight, folded as the radar folds it); without a
  declared velocity, range alone;
* none: the features are gated at the predicted range itself (a weak return there that the
  list's 10 dB floor left out still counts). If nothing is found there while the window holds
  targets, the policy rejects with `no-radar-target`; an empty window is `no-target`.

Not associated (the features take the strongest target of the window, as before): a claim
without a position, a position outside the recorded window (the radar looked elsewhere: the
target in view is measured and `range-mismatch` follows) and CW recordings. A CW radar measures
no range, so its one Doppler spectrum holds every target in the beam: nothing separates them,
and only the velocity residual of the strongest body line is checked (docs/policies.md).
Targets closer than `GATE_BINS` in range are one target to this radar (their returns share the
gate): the association cannot split them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from authn.kinematics import DeclaredState, Expected, residuals

__all__ = ["Association", "applies", "associate"]


@dataclass(frozen=True)
class Association:
    """How the analysed target was chosen.

    `gate`: the range (m) the features are gated at (None: the strongest target of the window);
    `in_view`: targets detected in the window (None: not counted, i.e. not associated);
    `candidates`: targets within the claim's range tolerance; `by`: `position` (one candidate),
    `velocity` (several: range and velocity picked; `range` when no velocity was declared),
    `declared-range` (no candidate: gated at the predicted range), `strongest` (not associated,
    see the module)."""

    gate: float | None
    in_view: int | None = None
    candidates: int = 0
    by: str = "strongest"

    def to_json(self) -> dict[str, Any]:
        return {"selected_by": self.by, "in_view": self.in_view, "candidates": self.candidates}


def applies(rec: Any, expected: Expected | None, state: DeclaredState | None) -> bool:
    """Whether the claim's target is chosen among the targets of `rec` (else: not associated,
    see the module)."""
    lo, hi = rec.config.range_window_m
    return expected is not None and state is not None and rec.domain != "cw" and lo <= expected.range_m < hi


def associate(rec: Any, expected: Expected | None, state: DeclaredState | None,
              targets: list[float] | None = None) -> Association:
    """The target of `rec` (a Recording) that the claim's predicted state (`expected`, from the
    declared `state`) matches; see the module for the rule. `targets`: the ranges (m) of the
    return's `detections`, when the caller has them (the feature stage's range profile); None:
    found here."""
    if expected is None or state is None or not applies(rec, expected, state):
        return Association(None)
    if targets is None:
        from signatures.features import detections

        targets = [r for r, _ in detections(rec)]
    lo, hi = rec.config.range_window_m
    bin_m = rec.config.range_bin_m(rec.n_samples)
    dop_m = rec.config.doppler_bin_mps(rec.n_chirps)
    v_amb = rec.config.measured_unambiguous_velocity_mps(rec.n_samples)

    def within(r: float) -> bool:
        res = residuals(expected, state, r, 0.0, bin_m, dop_m, v_amb)
        return lo <= r < hi and res.range_residual_m <= res.range_tolerance_m

    near = [r for r in targets if within(r)]
    if not near:
        return Association(expected.range_m, len(targets), 0, "declared-range")
    if len(near) == 1:
        return Association(near[0], len(targets), 1, "position")
    from signatures.features import extract

    def distance(r: float) -> float:
        v = extract(rec, expected_range_m=r, quick=True).radial_velocity_mps
        res = residuals(expected, state, r, float(v), bin_m, dop_m, v_amb)
        d = (res.range_residual_m / res.range_tolerance_m) ** 2
        if res.radial_velocity_residual_mps is not None and res.radial_velocity_tolerance_mps:
            d += (res.radial_velocity_residual_mps / res.radial_velocity_tolerance_mps) ** 2
        return d

    by = "velocity" if expected.radial_velocity_mps is not None else "range"
    return Association(min(near, key=distance), len(targets), len(near), by)
