"""Decisions over a track: one claim, many dwells of one target, one decision (docs/tracks.md).

`authn check --track` and `POST /v1/checks:track` feed a target's dwells, in time order, through
the single-dwell stages (`Checker.decide`, one dwell at a time) and combine their verification
log-likelihood ratios by Wald's sequential probability ratio test: after each dwell the
accumulated evidence is put to the Cedar policy, which accepts once it reaches the accept bound
and rejects once it falls to the reject bound (or on any other forbid: a kinematic mismatch in most
of at least `KINEMATIC_DWELLS` dwells, an implausible Remote ID, a registry fact). A dwell that sees
nothing (`no-target`) is no evidence: the track goes on while no dwell has seen its target. The
dwells after the deciding one are not read beyond their headers (the track is validated whole
first: one waveform, one claim, time order).

Bounds (Wald): with target error rates alpha (false accept: an impostor's track accepted) and
beta (false reject), accept at LLR >= log((1 - beta) / alpha) and reject at LLR <= log(beta /
(1 - alpha)). Wald's rates hold for independent, calibrated increments; ours are neither, so:

* dependence: one airframe's bias (its rotor rate, blades, aspect) repeats in every dwell of it.
  With intra-track correlation rho between dwell LLRs, n dwells carry the information of
  n_eff = n / (1 + (n - 1) rho) independent ones (the effective sample size of an equicorrelated
  mean), so the track LLR is n_eff times the mean increment: sum / (1 + (n - 1) rho). rho is
  measured on the simulator (`authn bench --track`, `lab.bench.track.dependence`): dwells of one
  scene with different simulator seeds against dwells of different scenes;
* a cap: no single dwell counts for more than `DWELL_CAP_NATS` either way, so one freak dwell
  (a clipped rate estimate, a classifier at its clip) cannot cross a bound alone;
* a dwell whose physics term abstained (the classifier alone) counts only against the claim: the
  classifier may count against a claim, never carry it.

A long dwell whose own flash train is too weak to read (or read at a multiple) is read at the rate the
track's own trains agree on, once they do, the dwells before that included (`_Reads`; docs/tracks.md,
"A track's rate"): nothing in it comes from the claim.

A single check is a track of one dwell: the same test, bounds, cap and policy rules decide it
(`Evidence.context` sends the same `track` record), so one dwell alone, capped below both default
bounds, is `inconclusive` unless a signature or another forbid decides. Each dwell's LLR is the least
over the alternatives registered at the site (`signatures.classify.verify`); over a track the increments are
summed per alternative and the least sum counts (`Sprt.track_llr`).

The per-dwell decisions are reported but decide nothing: the track decision is one complete
`is_authorized` over the track's evidence (the latest dwell's, the kinematic residual of the
dwells used at their lower median, every Remote ID issue seen) with a `track` context record; a policy or engine
error never accepts. One audit entry per track names every dwell used (file, SHA-256, terms)
and the skipped ones.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from datetime import datetime
from pathlib import Path
from typing import Any

from core.errors import AuthnError, describe, exit_code_for
from authn.sprt import (DEFAULT_FALSE_ACCEPT, DEFAULT_FALSE_REJECT, DWELL_CAP_NATS, DWELL_CORRELATION, Sprt)

__all__ = ["DEFAULT_FALSE_ACCEPT", "DEFAULT_FALSE_REJECT", "DWELL_CAP_NATS", "DWELL_CORRELATION", "KINEMATIC_DWELLS",
           "Dwell", "Sprt", "TrackOutcome", "check_track", "decide_track", "track_files"]

#: The one reason that lets a track go on to its next dwell (no bound crossed yet); a track (or a
#: single check) that ends with it is `inconclusive`.
INCONCLUSIVE = "radar-inconclusive"
#: Reasons a track goes on with: no bound crossed yet, and, while no dwell has seen the target, a
#: dwell that saw nothing (a missed detection is no evidence; a track whose dwells never see the
#: target ends rejected `no-target`).
GOES_ON = frozenset({INCONCLUSIVE, "no-target"})
#: Radar cannot separate the claim from a registered model (unsigned): no dwell can accept it, but the
#: evidence may still refute it (a Phantom 4 or a bird claiming an M300 where an M600 is registered),
#: so the track goes on while its LLR is below 0 and stops, inconclusive, once the radar favours the
#: claim (only a signature decides that).
CONFUSABLE = "radar-confusable-unsigned"
#: Kinematic forbids, which a later dwell can lift: the track judges its dwells' residuals at their
#: lower median (`_typical`), so one dwell whose body line went astray is outvoted by the next two.
KINEMATIC = frozenset({"range-mismatch", "velocity-mismatch"})
#: A kinematic forbid ends a track once this many dwells have been judged (then most of them miss),
#: or at the track's last dwell; before that the track goes on, as a first dwell read wrongly would
#: otherwise reject a track whose later dwells confirm it.
KINEMATIC_DWELLS = 3


@dataclass(frozen=True)
class Dwell:
    """One dwell of a track: its name, its header (`signatures.recording.Header`: waveform, time,
    Remote ID; cheap) and how to load it whole (the Recording and the SHA-256 of its bytes)."""

    name: str
    header: Callable[[], Any]
    load: Callable[[], tuple[Any, str]]

    @classmethod
    def file(cls, path: str | Path) -> "Dwell":
        from authn.check import CheckInput
        from signatures.recording import read_header

        p = Path(path)
        return cls(str(p), lambda: read_header(p), CheckInput.file(p).load)

    @classmethod
    def recording(cls, rec: Any, name: str = "", digest: str = "") -> "Dwell":
        """An in-memory recording (benchmarks, tests)."""
        from signatures.recording import Header

        head = Header(rec.config, rec.site, rec.start_time, (rec.n_chirps, rec.n_samples), rec.domain,
                      rec.remote_id, rec.remote_id_time_s)
        return cls(name, lambda: head, lambda: (rec, digest))


def track_files(paths: Sequence[Path]) -> list[Path]:
    """The dwells of `--track`: one directory (its .h5/.hdf5/.npz files by name, as `authn import`
    numbers them) or the files in the order given. No dwell at all is bad input."""
    if len(paths) == 1 and paths[0].is_dir():
        from signatures.recording import recordings_in

        found = recordings_in(paths[0])
        if not found:
            raise AuthnError(f"{paths[0]}: no .h5/.npz files in this directory: a track needs at least one dwell")
        return found
    for p in paths:
        if p.is_dir():
            raise AuthnError(f"{p}: a track is one directory or a list of files, not both")
    if not paths:
        raise AuthnError("a track needs at least one dwell")
    return list(paths)


def _basic_serial(head: Any) -> str | None:
    from remoteid import BasicId
    from remoteid.codec import decode_rows_raw

    if head.remote_id is None:
        return None
    basic = next((m for m, _ in decode_rows_raw(head.remote_id) if isinstance(m, BasicId) and m.uas_id), None)
    return basic.uas_id.strip() if basic else None


def _validate(dwells: Sequence[Dwell], serial: str | None) -> str:
    """Read every dwell's header and refuse a track that is not one target's: mixed waveforms,
    mixed claims (the serials its Remote ID declares, or none to claim), dwells out of time order.
    Returns the claimed serial."""
    if not dwells:
        raise AuthnError("a track needs at least one dwell")
    first = None
    claimed: tuple[str, str] | None = None  # (serial, the dwell that declared it)
    prev: tuple[datetime, str] | None = None
    for d in dwells:
        head = d.header()
        wave = (head.config.to_dict(exclude=("range_offset_m",)), head.domain, head.shape)  # the window may move
        if first is None:
            first = (wave, d.name)
        elif wave != first[0]:
            raise AuthnError(f"{d.name}: its waveform differs from {first[1]}'s: a track is one radar waveform")
        declared = _basic_serial(head)
        if declared is not None:
            if claimed is not None and declared != claimed[0]:
                raise AuthnError(f"{d.name}: its Remote ID declares {declared!r}, {claimed[1]} declares "
                                 f"{claimed[0]!r}: a track is one claim")
            claimed = claimed or (declared, d.name)
        elif serial is None:
            raise AuthnError(f"{d.name}: no claim: give --serial, or dwells whose Remote ID carries a Basic ID serial")
        if prev is not None and head.start_time <= prev[0]:
            raise AuthnError(f"{d.name}: starts at {head.start_time.isoformat()}, not after {prev[1]} "
                             f"({prev[0].isoformat()}): a track's dwells must be in time order")
        prev = (head.start_time, d.name)
    return serial if serial is not None else claimed[0]  # type: ignore[index]


@dataclass
class DwellTerm:
    """What one dwell of a track added: its verification LLR (None: nothing verified), the capped
    increment, its kinematics, and what the single-dwell policy said of it alone (reported only)."""

    file: str
    file_sha256: str
    dwell_start: str
    radar_model: str | None
    llr: float | None
    increment: float | None
    terms: dict[str, float]
    kinematics: dict[str, Any] | None
    decision: str
    reasons: list[str]
    #: the increment against each alternative (`Sprt.increments`); None: nothing verified
    against: dict[str, float] | None = None
    #: the flash rate the physics term compared (`Verification.compared`: measured, claimed, and
    #: `track_rate` where the dwell was read at the track's rate); None: no physics term
    flash_rate: dict[str, float] | None = None

    def to_json(self) -> dict[str, Any]:
        return {"file": self.file, "file_sha256": self.file_sha256, "dwell_start": self.dwell_start,
                "radar_model": self.radar_model, "llr": None if self.llr is None else round(self.llr, 4),
                "increment": None if self.increment is None else round(self.increment, 4),
                "terms": {k: round(v, 4) for k, v in self.terms.items()}, "kinematics": self.kinematics,
                "dwell_decision": self.decision, "dwell_reasons": list(self.reasons),
                **({"against": {k: round(v, 4) for k, v in self.against.items()}} if self.against is not None else {}),
                **({"flash_rate": {k: round(v, 3) for k, v in self.flash_rate.items()}} if self.flash_rate else {})}


@dataclass
class TrackOutcome:
    """The track's decision, the evidence and request it was made on, and each dwell's terms."""

    decision: str
    reasons: list[str]
    evidence: Any  # authn.evidence.Evidence of the final request
    policy_input: dict[str, Any]
    sprt: Sprt
    llr: float
    dwells: list[DwellTerm]
    dwells_used: int
    skipped: list[str]
    policy_sha256: str
    policy_errors: list[str] = field(default_factory=list)
    timings_ms: dict[str, float] = field(default_factory=dict)
    audit_id: int | None = None

    @property
    def serial(self) -> str:
        return self.evidence.claim.serial

    def why(self) -> str:
        """Why the track ended where it did, in words: refuted, accepted or rejected after so many
        dwells, stopped early by a forbid more dwells cannot lift, or inconclusive because it ran
        out of dwells with neither bound crossed."""
        n, total = len(self.dwells), len(self.dwells) + len(self.skipped)
        after = f"after {n} of {total} dwell{'s' if total != 1 else ''}"
        s, reasons = self.sprt, ", ".join(self.reasons)
        if self.decision == "accept":
            how = f" >= {s.accept_nats:.2f}" if self.llr >= s.accept_nats else ", with a valid DRIP signature"
            return f"the claim is accepted {after}: LLR {self.llr:+.2f} nats{how}"
        if not self.dwells_used:
            return f"{self.decision} {after}, before the radar ran: {reasons}"
        if {"radar-claim-inconsistent", "radar-not-a-drone"} & set(self.reasons):
            track = self.policy_input.get("context", {}).get("track", {})
            refute = track.get("refute_llr_cn", track.get("llr_cn", 0)) / 100.0
            return f"the claim is refuted {after}: LLR {refute:+.2f} nats <= {s.reject_nats:.2f} ({reasons})"
        if self.decision == "reject":
            return f"rejected {after}: {reasons}" + (" (more dwells cannot lift it)" if self.skipped else "")
        if self.skipped:
            return f"stopped {after}: {reasons} (more dwells cannot decide it; a valid DRIP signature can)"
        return (f"inconclusive: all {total} dwell{'s' if total != 1 else ''} read and neither bound crossed "
                f"(LLR {self.llr:+.2f} nats; refute <= {s.reject_nats:.2f}, accept >= {s.accept_nats:.2f})")

    def to_json(self) -> dict[str, Any]:
        """What `authn check --track --json` prints (docs/tracks.md)."""
        report = self.evidence.report()
        return {"track": True, "decision": self.decision, "reasons": list(self.reasons),
                "claim": report["claim"], "registry": report["registry"],
                "llr": round(self.llr, 4), "sprt": self.sprt.to_json(),
                "why": self.why(), "dwells_used": self.dwells_used, "dwells_read": len(self.dwells),
                "dwells_skipped": len(self.skipped), "skipped_files": list(self.skipped),
                "dwells": [d.to_json() for d in self.dwells], "radar": report["radar"],
                "kinematics": report["kinematics"], "remote_id": report["remote_id"],
                "remote_id_auth": report["remote_id_auth"], "policy_sha256": self.policy_sha256,
                "policy_errors": list(self.policy_errors), "timings_ms": dict(self.timings_ms),
                "audit_id": self.audit_id,
                **({"to_decide": self.evidence.to_decide([d.against for d in self.dwells if d.against is not None])}
                   if self.decision == "inconclusive" else {})}

    def audit_payload(self) -> dict[str, Any]:
        doc = self.to_json()
        doc.pop("audit_id")
        doc.pop("timings_ms")
        doc["policy_input"] = self.policy_input
        return doc


def _term(o: Any, sprt: Sprt) -> DwellTerm:
    radar = o.evidence.radar
    v = radar.verification if radar is not None else None
    llr = v.llr if v is not None and v.terms else None
    kin = o.evidence.kinematics
    per = next(iter(o.evidence.increments(sprt)), None)
    rate = v.compared.get("flash_rate_hz") if v is not None else None
    return DwellTerm(o.file, o.file_sha256, o.evidence.report()["dwell_start"],
                     None if radar is None else radar.model, llr, None if per is None else min(per.values()),
                     dict(v.terms) if v is not None else {}, None if kin is None else kin.to_json(),
                     o.decision, list(o.reasons), per, dict(rate) if rate else None)


def _typical(kinematics: list[Any]) -> Any:
    """The kinematic evidence of the track: of its dwells' residuals (each the larger of range and
    radial velocity over its tolerance), the lower median's dwell. A declared position or velocity
    that misses the radar's in more than half of the dwells used forbids; one dwell whose own
    estimate went astray (a moving body's line lost at 0 dB, read at zero Doppler) does not reject
    a track that many more dwells confirm, as the worst dwell would in every long enough track.
    A one-dwell track is judged on its dwell."""
    def ratio(k: Any) -> float:
        r = k.residuals
        parts = [r.range_residual_m / max(r.range_tolerance_m, 1e-9)] if k.range_measured else []
        if r.radial_velocity_residual_mps is not None:
            parts.append(r.radial_velocity_residual_mps / max(r.radial_velocity_tolerance_mps, 1e-9))
        return max(parts, default=0.0)

    if not kinematics:
        return None
    ranked = sorted(kinematics, key=ratio)
    return ranked[(len(ranked) - 1) // 2]


def _track_evidence(outcomes: list[Any], sprt: Sprt | None = None) -> Any:
    """The evidence the track request is built on: the latest dwell's claim, registry and Remote
    ID authentication; the radar of the latest dwell that saw a target; the typical kinematics of
    the dwells (`_typical`); every Remote ID issue any dwell raised."""
    last = outcomes[-1].evidence
    seen = [o.evidence.radar for o in outcomes if o.evidence.radar is not None and o.evidence.radar.detected]
    return replace(last, radar=seen[-1] if seen else last.radar,
                   kinematics=_typical([o.evidence.kinematics for o in outcomes if o.evidence.kinematics is not None]),
                   remote_id_issues=list(dict.fromkeys(i for o in outcomes for i in o.evidence.remote_id_issues)),
                   sprt=sprt or last.sprt)


class _Reads:
    """A track's dwells as read so far: each one's outcome and term, and the track's rate it was
    read at (None: its own read). Once the dwells' own trains agree on a rate
    (`signatures.classify.track_rate.consensus_rate`; a dwell read at the track's rate does not
    vote), every dwell so far whose own read is no train there, and that was not read at about
    that rate yet, is read again at it (`CheckInput.track_rate_hz`), the earlier ones included:
    the test then weighs them all as read at the track's rate (docs/tracks.md, "A track's rate")."""

    def __init__(self, checker: Any, claim: str, serial: str | None, sprt: Sprt, timings: dict[str, float]) -> None:
        self.checker, self.claim, self.serial, self.sprt, self.timings = checker, claim, serial, sprt, timings
        self.dwells: list[Dwell] = []
        self.outcomes: list[Any] = []
        self.terms: list[DwellTerm] = []
        self.read_at: list[float | None] = []

    def add(self, d: Dwell) -> Any:
        """Read the next dwell (at the track's rate so far), then any dwell a new track rate reads
        again; returns the new dwell's outcome."""
        rate = self.rate()
        o = self._decide(d, rate)
        self.dwells.append(d)
        self.outcomes.append(o)
        self.terms.append(_term(o, self.sprt))
        self.read_at.append(rate)
        if o.evidence.radar is not None:
            self._read_again()
        return o

    def rate(self) -> float | None:
        """The flash rate the dwells' own trains agree on (None: not yet)."""
        from signatures.classify.track_rate import consensus_rate

        return consensus_rate([t.flash_rate["measured"] for t in self.terms
                               if t.flash_rate and "track_rate" not in t.flash_rate])

    def increments(self) -> list[dict[str, float]]:
        return [t.against for t in self.terms if t.against is not None]

    def _read_again(self) -> None:
        from signatures.dsp.flash_spectrum import TRACK_RATE_WINDOW

        rate = self.rate()
        if rate is None:
            return
        near = TRACK_RATE_WINDOW * rate
        for i, t in enumerate(self.terms):
            own = t.flash_rate if t.flash_rate and "track_rate" not in t.flash_rate else None
            at = self.read_at[i]
            if (self.outcomes[i].evidence.radar is None or (own is not None and abs(own["measured"] - rate) <= near)
                    or (at is not None and abs(at - rate) <= near)):
                continue
            self.outcomes[i] = self._decide(self.dwells[i], rate)
            self.terms[i] = _term(self.outcomes[i], self.sprt)
            self.read_at[i] = rate

    def _decide(self, d: Dwell, rate: float | None) -> Any:
        from authn.check import CheckInput, Failure

        batch = self.checker.decide([CheckInput(d.name, self.claim if self.serial is not None else None, d.load,
                                                track=True, track_rate_hz=rate)])
        if batch.fault is not None:
            raise batch.fault
        o = batch.items[0]
        if isinstance(o, Failure):
            o.raise_()
        for k, v in o.timings_ms.items():
            self.timings[k] = round(self.timings.get(k, 0.0) + v, 3)
        if o.serial != self.claim:  # validated from the header; the full read must agree
            raise AuthnError(f"{d.name}: claims {o.serial!r}, the track claims {self.claim!r}")
        return o


def _request(ev: Any, sprt: Sprt, increments: Sequence[Mapping[str, float]]) -> dict[str, Any]:
    """The Cedar request of the track: the evidence's, with the `track` record over its dwells in
    place of a single dwell's (the same record a single check sends: one rule, docs/policies.md)."""
    ctx = ev.context()
    if ev.radar_confusable_track is not None:  # confusable by the track-level separation
        ctx["radar_confusable"] = ev.radar_confusable_track
    ctx["track"] = sprt.record(increments)
    return {"serial": ev.claim.serial, "principal": ev.principal(), "resource": ev.resource(), "context": ctx}


def decide_track(checker: Any, dwells: Sequence[Dwell], serial: str | None = None,
                 sprt: Sprt | None = None) -> TrackOutcome:
    """Decide a track (not recorded): validate it whole from the headers, then one dwell at a time
    until the policy decides (module docstring). Bad input anywhere in the track raises (exit 2),
    naming the dwell; a database or engine fault raises SystemFault."""
    sprt = sprt or Sprt()
    t0 = time.perf_counter()
    claim = _validate(dwells, serial)
    timings = {"validate": round((time.perf_counter() - t0) * 1e3, 3)}
    reads = _Reads(checker, claim, serial, sprt, timings)
    result = request = None
    for d in dwells:
        o = reads.add(d)
        if o.evidence.radar is None:  # the registry decided before any radar: final, whatever follows
            from authn.policy import PolicyResult

            request = o.request  # the request that decided it, as sent
            result = PolicyResult(o.decision, list(o.reasons), list(o.policy_errors), request)
            break
        ev = _track_evidence(reads.outcomes, sprt)
        request = _request(ev, sprt, reads.increments())
        t1 = time.perf_counter()
        result = checker.policy.decide(claim, request["principal"], request["resource"], request["context"])
        request = result.request
        timings["policy_track"] = round(timings.get("policy_track", 0.0) + (time.perf_counter() - t1) * 1e3, 3)
        judged = sum(1 for o in reads.outcomes if o.evidence.kinematics is not None)
        liftable = GOES_ON | KINEMATIC if judged < KINEMATIC_DWELLS and len(reads.outcomes) < len(dwells) else GOES_ON
        if request["context"].get("track", {}).get("llr_cn", 0) < 0:
            liftable |= {CONFUSABLE}
        if result.decision == "accept" or not set(result.reasons) <= liftable:
            break  # accepted, or a forbid more dwells cannot lift
    if result is None or request is None:  # unreachable: _validate refuses an empty track
        raise AuthnError("a track needs at least one dwell")
    outcomes = reads.outcomes
    radar_used = sum(1 for o in outcomes if o.evidence.radar is not None)
    return TrackOutcome(decision=result.decision, reasons=list(result.reasons),
                        evidence=_track_evidence(outcomes, sprt) if radar_used else outcomes[-1].evidence,
                        policy_input=request, sprt=sprt, llr=sprt.track_llr(reads.increments()), dwells=reads.terms,
                        dwells_used=radar_used, skipped=[d.name for d in dwells[len(outcomes):]],
                        policy_sha256=checker.policy.sha256, policy_errors=list(result.errors), timings_ms=timings)


def _error_entry(names: Sequence[str], serial: str | None, exc: BaseException, policy_sha256: str) -> Any:
    from authn.audit import AuditLog

    return AuditLog.error(names[0] if names else "", serial, describe(exc), exit_code_for(exc),
                          policy_sha256=policy_sha256, track_files=names)


def check_track(checker: Any, dwells: Sequence[Dwell], serial: str | None = None,
                sprt: Sprt | None = None) -> TrackOutcome:
    """Decide a track and record it: one audit entry (the decision, or the error that stopped it)
    committed before this returns or raises; a commit that fails raises (nothing to print)."""
    from authn.audit import AuditLog

    log = AuditLog(checker.db, checker.policy.text)
    try:
        out = decide_track(checker, dwells, serial, sprt)
    except Exception as exc:
        try:
            log.record([_error_entry([d.name for d in dwells], serial, exc, checker.policy.sha256)])
        except Exception:  # noqa: BLE001 - the error that stopped the track is the one reported
            pass
        raise
    t0 = time.perf_counter()
    out.audit_id = log.record_decision(out.serial, out.decision, out.audit_payload()).seq
    out.timings_ms["audit"] = round((time.perf_counter() - t0) * 1e3, 3)
    return out
