"""`authn check`: gather evidence for one claim, decide with Cedar, record in the audit log.

Stages run in the order that lets cheap facts decide first:
read -> remote_id -> registry -> policy with the radar not run
-> [radar: features at the expected range, classifier, kinematics] -> policy -> audit.
When the registry facts already force a rejection (a satisfied forbid policy that reads
no context, see `authn.policy`) the radar stages are skipped and listed in `skipped`;
the decision always comes from a complete `is_authorized` call over the evidence gathered.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from functools import partial
from datetime import datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any

from authn.audit import AuditLog, NewEntry
from authn.audit.log import signing_warmed
from core.digest import file_sha256
from core.errors import EXIT_BAD_INPUT, describe, exit_code_for
from core.uasid import as_heard
from authn.evidence import (Claim, Evidence, KinematicsEvidence, RadarEvidence, RegistryFacts, RemoteIdAuth,
                            authenticate, read_claim)
from authn.kinematics import expected_from_radar, residuals, sanity
from authn.policy import PolicyEngine

if TYPE_CHECKING:
    from authn.association import Association
    from authn.kinematics import Expected
    from authn.policy import PolicyResult
    from authn.sprt import Sprt
    from remoteid.capture import Broadcaster, CapturedMessage
    from signatures.dsp.extraction import Chooser
    from signatures.dsp.feature_vector import FeatureResult
    from signatures.classify.inference import Classifier, Prediction
    from signatures.profiles import UavProfile
    from signatures.recording import Recording
    from signatures.classify.verify import Verification

RADAR_STAGES = ("radar_features", "classify", "kinematics")
#: A return's place in a batch: (input, claim of that input: a capture names several drones)
Key = tuple[int, int]


@dataclass(frozen=True)
class Outcome:
    """A decision, the typed evidence it was made on and the Cedar request that made it
    (`request`, as sent: what the audit keeps for `authn audit replay`). Frozen; the evidence's
    JSON view is rendered once, at construction, and both `to_json` (what `authn check --json`
    prints) and `audit_payload` are assembled from that one rendering."""

    file: str
    decision: str
    reasons: tuple[str, ...]
    evidence: Evidence
    skipped: tuple[str, ...]
    timings_ms: Mapping[str, float]
    policy_sha256: str
    file_sha256: str
    request: dict[str, Any]
    #: Cedar's evaluation errors (a non-empty list means the claim was rejected with `policy-error`)
    policy_errors: tuple[str, ...] = ()
    audit_id: int | None = None
    #: with a Remote ID capture: the return's radar targets that no claim explains
    #: (`Checker._non_cooperative`); None without a capture
    non_cooperative: tuple[dict[str, float], ...] | None = None
    #: (the evidence rendered, its report and `to_decide`): set at construction, carried by `recorded`
    rendered: tuple[Evidence, dict[str, Any], dict[str, Any]] | None = field(default=None, compare=False, repr=False)

    def __post_init__(self) -> None:
        if self.rendered is None or self.rendered[0] is not self.evidence:
            extra = {"to_decide": self.evidence.to_decide()} if self.decision == "inconclusive" else {}
            object.__setattr__(self, "rendered", (self.evidence, self.evidence.report(), extra))

    @classmethod
    def of(cls, file: str, digest: str, result: PolicyResult, evidence: Evidence, timer: _Timer,
           policy_sha256: str) -> "Outcome":
        return cls(file=file, decision=result.decision, reasons=tuple(result.reasons), evidence=evidence,
                   skipped=tuple(s for s in RADAR_STAGES if s not in timer.ms), timings_ms=dict(timer.ms),
                   policy_sha256=policy_sha256, file_sha256=digest, request=result.request,
                   policy_errors=tuple(result.errors))

    def recorded(self, seq: int, audit_ms: float) -> "Outcome":
        """This outcome as recorded: its audit entry and the audit's share of the time."""
        return replace(self, audit_id=seq, timings_ms={**self.timings_ms, "audit": audit_ms})

    def with_non_cooperative(self, targets: list[dict[str, float]]) -> "Outcome":
        return replace(self, non_cooperative=tuple(dict(t) for t in targets))

    @property
    def serial(self) -> str:
        return self.evidence.claim.serial

    @property
    def radar(self) -> RadarEvidence | None:
        return self.evidence.radar

    @property
    def model_card_sha256(self) -> str | None:
        return self.evidence.radar.model_card_sha256 if self.evidence.radar else None

    def _document(self, audited: bool) -> dict[str, Any]:
        _, report, extra = self.rendered  # type: ignore[misc]
        doc: dict[str, Any] = {"file": self.file, "decision": self.decision, "reasons": list(self.reasons),
                               "dwell_start": report["dwell_start"], "claim": report["claim"],
                               "registry": report["registry"], "radar": report["radar"],
                               "kinematics": report["kinematics"], "remote_id": report["remote_id"],
                               "skipped": list(self.skipped)}
        if audited:
            doc["timings_ms"] = dict(self.timings_ms)
        doc.update(policy_sha256=self.policy_sha256, model_card_sha256=self.model_card_sha256,
                   file_sha256=self.file_sha256, remote_id_auth=report["remote_id_auth"],
                   policy_errors=list(self.policy_errors))
        if audited:
            doc["audit_id"] = self.audit_id
        if self.non_cooperative is not None:
            doc["non_cooperative"] = [dict(t) for t in self.non_cooperative]
        doc.update(extra)
        return doc

    def to_json(self) -> dict[str, Any]:
        """What `authn check --json` prints (docs/output.md)."""
        return self._document(audited=True)

    def audit_payload(self) -> dict[str, Any]:
        """The audit entry's payload: the JSON without timings and audit id, with the exact
        Cedar request (`authn audit replay` re-runs it)."""
        return {**self._document(audited=False), "policy_input": self.request}


@dataclass(frozen=True)
class Failure:
    """A check that ended without a decision: bad input (exit 2) or a system fault (exit 3)."""

    file: str
    serial: str | None
    error: str
    exit_code: int = EXIT_BAD_INPUT
    exc: BaseException | None = field(default=None, compare=False, repr=False)  # what raised, when one did

    @classmethod
    def of(cls, file: str, serial: str | None, exc: BaseException) -> "Failure":
        return cls(file, serial, describe(exc), exit_code_for(exc), exc)

    def raise_(self) -> None:
        """Raise what stopped this check: bad input as itself (its message), anything else as
        a SystemFault naming the file."""
        from core.errors import SystemFault

        if self.exit_code == EXIT_BAD_INPUT and self.exc is not None:
            raise self.exc
        raise SystemFault(f"{self.file}: {self.error}")

    def entry(self, policy_sha256: str | None) -> NewEntry:
        return AuditLog.error(self.file, self.serial, self.error, self.exit_code, policy_sha256=policy_sha256)

    def to_json(self) -> dict[str, Any]:
        return {"file": self.file, "error": self.error, "exit_code": self.exit_code}


class _Timer:
    def __init__(self) -> None:
        self.ms: dict[str, float] = {}

    @contextmanager
    def stage(self, name: str) -> Iterator[None]:
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self.ms[name] = round(self.ms.get(name, 0.0) + (time.perf_counter() - t0) * 1e3, 3)  # a stage may recur


def _shares(timers: Sequence[_Timer], name: str, t0: float, less_ms: float = 0.0) -> None:
    """Each of `timers` its share of one call over all of them, begun at `t0`, less `less_ms`
    (time inside it already counted under another stage)."""
    share = round(max(0.0, (time.perf_counter() - t0) * 1e3 - less_ms) / max(len(timers), 1), 3)
    for t in timers:
        t.ms[name] = share


def _batch_size(rec: Recording) -> int:
    from signatures.features import batch_size

    return batch_size(rec.n_chirps, rec.n_samples)


def _issues(claim: Claim, auth: RemoteIdAuth, mid: datetime, rotorcraft: bool | None) -> list[str]:
    """Remote ID sanity issues; with a valid signature, a Location message it does not cover
    is one too (`unsigned-location`: someone may be broadcasting beside the signer)."""
    from remoteid import Location

    issues = sanity(claim.state, claim.ua_type, claim.rid_serial, claim.serial, mid, rotorcraft)
    if auth.status == "valid" and any(isinstance(m, Location) and i not in auth.covered
                                      for i, (m, _) in enumerate(claim.wire)):
        issues.append("unsigned-location")
    return issues


@dataclass(frozen=True)
class _Front:
    """A check up to the policy with the radar not run: its evidence and that request, built once."""

    rec: Recording
    claim: Claim
    auth: RemoteIdAuth
    evidence: Evidence
    request: dict[str, Any]
    file: str
    digest: str
    timer: _Timer
    track: bool
    #: a track's dwell: the rate the track's dwells so far agree on (`signatures.classify.track_rate`)
    track_rate_hz: float | None = None


@dataclass(frozen=True)
class _Pending:
    """A check the registry facts did not decide: what its radar stages and final decision need."""

    front: _Front
    evidence: Evidence  # the front's, with the bundle's facts (preset, confusable models, separation)
    classifier: Classifier
    claimed: UavProfile | None  # the registered model's profile (None: no profile)
    expected: Expected | None  # the radar-frame state the Remote ID predicts (None: no position)
    #: how the claim's target was chosen; its `gate` is the range features are gated at (None: chosen
    #: by the feature stage from the return's range profile, `Checker._features`)
    association: Association | None
    #: a signed claim of a radar-confusable model: the registered models it is verified together with
    group: tuple[UavProfile, ...] = ()
    #: the other models registered at the site: the alternatives the claim must win against
    alternatives: tuple[UavProfile, ...] = ()

    @property
    def rec(self) -> Recording:
        return self.front.rec

    @property
    def timer(self) -> _Timer:
        return self.front.timer

    @property
    def gate(self) -> float | None:
        return None if self.association is None else self.association.gate

    def expected_range(self, chosen: dict[Key, Association], key: Key) -> float | Chooser | None:
        """What the feature stage gates at: the association's range, or a chooser that associates
        from the return's targets (found on the feature stage's own range profile) into `chosen`."""
        if self.association is not None:
            return self.association.gate

        def choose(targets: list[tuple[float, float]]) -> float | None:
            from authn.association import associate

            with self.timer.stage("associate"):
                chosen[key] = associate(self.rec, self.expected, self.front.claim.state, [r for r, _ in targets])
            return chosen[key].gate

        return choose


class _Memo:
    """Answers kept for one batch: each key's function runs once (a failure is not kept, so
    each return that asks again raises its own error)."""

    def __init__(self) -> None:
        self._kept: dict[tuple, Any] = {}

    def __call__(self, key: tuple, fn: Callable[[], Any]) -> Any:
        if key not in self._kept:
            self._kept[key] = fn()
        return self._kept[key]


def _flag(confusable: tuple[str, ...] | None) -> bool | None:
    """A `_confusable_models` answer as the policy's `radar_confusable` (None: not a site bundle)."""
    return None if confusable is None else bool(confusable)


@dataclass(frozen=True)
class CheckInput:
    """One return to check: its name (file or upload), the claimed serial (None: the return's
    Remote ID), and how to load it, giving the Recording and the SHA-256 of its bytes."""

    name: str
    serial: str | None
    load: Callable[[], tuple[Recording, str]]
    #: a Remote ID capture heard beside the radar (`--rid-capture`): its messages replace the
    #: return's own, one claim per drone heard in the dwell's window (docs/remoteid.md)
    rid_capture: "RidCapture | None" = None
    #: a dwell of a track (`authn check --track`): radar-confusable models are those of the site
    #: card's track-level errors, the level the track decides at
    track: bool = False
    #: a track's dwell: the flash rate the track's earlier dwells agree on, which this dwell is read
    #: at where its own read shows no train there (`signatures.classify.track_rate`); None: its own
    track_rate_hz: float | None = None
    #: this check's error targets (`authn.sprt.Sprt`; None: the Checker's)
    sprt: Sprt | None = None

    @classmethod
    def file(cls, path: str | Path, serial: str | None = None, rid_capture: "RidCapture | None" = None) -> "CheckInput":
        from signatures.recording import read_recording

        p = Path(path)
        return cls(str(p), serial, lambda: (read_recording(p), file_sha256(p)), rid_capture)

    @classmethod
    def recording(cls, rec: Recording, serial: str | None = None, name: str = "", digest: str = "") -> "CheckInput":
        """An in-memory recording (benchmarks, the stress suite, uploads already read)."""
        return cls(name, serial, lambda: (rec, digest))


#: Most drones one capture may name in a dwell's window, each its own decision and audit entry
#: (`authn check --max-drones`, `authn serve --max-drones`): more is refused before any is decided.
MAX_DRONES = 64


@dataclass(frozen=True)
class RidCapture:
    """A pcap/pcapng capture of Remote ID, the clock-skew tolerance it is aligned with, and the
    most drones it may name in one dwell's window (`max_drones`; `raise_with` says how to raise it)."""

    name: str
    #: the CapturedMessages (remoteid.capture) of the packets in a time window; raises CaptureError
    read: Callable[[tuple[datetime, datetime]], list[CapturedMessage]]
    skew_s: float = 2.0
    max_drones: int = MAX_DRONES
    raise_with: str = "--max-drones"

    @classmethod
    def file(cls, path: str | Path, skew_s: float = 2.0, max_drones: int = MAX_DRONES) -> "RidCapture":
        from remoteid.capture import read_capture

        return cls(str(path), lambda window: read_capture(path, window), skew_s, max_drones)

    @classmethod
    def data(cls, name: str, data: bytes, skew_s: float = 2.0, max_drones: int = MAX_DRONES,
             raise_with: str = "--max-drones") -> "RidCapture":
        from remoteid.capture import extract
        from remoteid.errors import CaptureError

        def read(window: tuple[datetime, datetime]) -> list[CapturedMessage]:
            try:
                return extract(data, window)
            except CaptureError as exc:  # name the upload, as read_capture names a file
                raise CaptureError(f"{name}: {exc}") from None

        return cls(name, read, skew_s, max_drones, raise_with)

    def heard(self, rec: Recording) -> list[Broadcaster]:
        """The drones (`remoteid.capture.Broadcaster`) heard in the dwell's window, by UAS ID;
        nothing heard at all is bad input."""
        from core.errors import AuthnError
        from remoteid.capture import WINDOW_MARGIN_S, broadcasters, window

        end = rec.start_time + (rec.mid_time - rec.start_time) * 2
        found, unattributed = broadcasters(self.read(window(rec.start_time, end, self.skew_s)), rec.start_time, end,
                                           self.skew_s)
        if not found:
            margin = WINDOW_MARGIN_S + max(self.skew_s, 0.0)
            raise AuthnError(f"{self.name}: no Remote ID message with a UAS ID in the dwell's window "
                             f"({rec.start_time.isoformat()} to {end.isoformat()} +- {margin:g} s"
                             + (f"; {unattributed} messages from transmitters that sent no Basic ID" if unattributed
                                else "") + ")")
        return sorted(found, key=lambda b: b.uas_id)

    @staticmethod
    def with_messages(rec: Recording, b: Broadcaster) -> Recording:
        """The return with the messages of one drone heard (its own Remote ID replaced)."""
        from dataclasses import replace as dreplace

        import numpy as np

        rows = np.frombuffer(b"".join(b.rows), dtype=np.uint8).reshape(-1, 25).copy()
        return dreplace(rec, remote_id=rows, remote_id_time_s=np.asarray(b.heard_s, dtype=np.float64),
                        remote_id_source="capture")

    def claims(self, rec: Recording, serial: str | None) -> list[tuple[Recording, str | None, Broadcaster | None]]:
        """(the return with one drone's messages, the serial to claim, the drone heard:
        `remoteid.capture.Broadcaster`) for each drone heard in the dwell's window; with `serial`,
        that drone only (no Remote ID at all when it was not heard, and no drone: rejected with
        no-remote-id). Nothing heard at all in the window is bad input."""
        from dataclasses import replace as dreplace

        found = self.heard(rec)
        if serial is None:
            self._within_cap(len(found))
            return [(self.with_messages(rec, b), None, b) for b in found]
        match = [b for b in found if b.uas_id == as_heard(serial)]
        if not match:
            return [(dreplace(rec, remote_id=None, remote_id_time_s=None, remote_id_source=None), serial, None)]
        return [(self.with_messages(rec, match[0]), serial, match[0])]

    def _within_cap(self, drones: int) -> None:
        """More drones than `max_drones` is bad input (OverLimit), refused before any is decided."""
        from core.errors import OverLimit

        if drones > self.max_drones:
            raise OverLimit(f"{self.name}: {drones} drones heard in the dwell's window, more than the limit of "
                            f"{self.max_drones} decisions per capture (raise it with {self.raise_with}, or "
                            "name one drone with a serial)")

    def attach(self, rec: Recording, serial: str | None = None) -> Recording:
        """The return with the messages of the one drone heard in its window (`authn import
        --rid-capture`); with several drones heard, `serial` must name one."""
        from core.errors import AuthnError

        found = self.heard(rec)
        ids = ", ".join(b.uas_id for b in found)
        if serial is not None:
            found = [b for b in found if b.uas_id == as_heard(serial)]
            if not found:
                raise AuthnError(f"{self.name}: nothing from {serial} in the dwell's window (heard: {ids})")
        if len(found) > 1:
            raise AuthnError(f"{self.name}: {len(found)} drones heard in the dwell's window ({ids}); "
                             "name one with --rid-serial")
        if found[0].conflict:  # the file could not keep which transmitter sent what
            raise AuthnError(f"{self.name}: {found[0].uas_id}: conflicting transmitters in the dwell's window ("
                             + "; ".join(f"{t} sent {', '.join(u)}" for t, u in found[0].conflict) + ")")
        return self.with_messages(rec, found[0])


@dataclass(frozen=True)
class Batch:
    """What `Checker.decide` decided, in input order; `fault`: the SystemFault that stopped it
    (each return read and left undecided by it is a Failure, the last item one; the returns after
    it were not checked)."""

    items: list[Outcome | Failure]
    fault: BaseException | None = None


class Checker:
    """Loads once what every check needs (policy, database, file reader; the classifier on
    first radar use); checks many files."""

    def __init__(self, db_url: str | None = None, policy_path: str | Path | None = None,
                 trusted_registries: dict[bytes, bytes] | None = None, model: str | Path | None = None,
                 sprt: Sprt | None = None) -> None:
        import h5py  # noqa: F401  every check opens an HDF5 file: load the library at start-up

        from registry.dbapi import Database
        from signatures.recording import read_recording

        self.policy = PolicyEngine.load(policy_path)
        self.trusted_registries = trusted_registries or {}  # HDA DET -> key whose DRIP Links are believed
        self.db = Database(db_url)
        self._read = read_recording
        self.model = model  # a bundle folder that must serve every file (`--model`); None: by waveform
        #: the sequential test the radar's evidence is put to, one dwell or many (`authn.sprt.Sprt`;
        #: None: its default error targets)
        self.sprt = sprt
        if model is not None:
            from signatures.classify.inference import load_classifier

            load_classifier(path=model)  # a bad bundle stops here, not once per file

    # --- stages -------------------------------------------------------------------

    @staticmethod
    def _verify(feats: FeatureResult, pred: Prediction, claimed: UavProfile | None, rec: Recording,
                classifier: Classifier | None = None, group: tuple[UavProfile, ...] = (),
                alternatives: tuple[UavProfile, ...] = (), track_rate_hz: float | None = None) -> Verification | None:
        """1:1 verification of the return against the registered model's profile (None: no profile),
        with the claimed model's site bands and the site's score calibration where a site bundle
        has them; against the claim and `group` together (a signed claim of a radar-confusable
        model, `_group`) where `group` names models; against each of `alternatives` (the other
        registered models, with their site bands) and the background. A track's dwell is read at
        `track_rate_hz` where its own read shows no train there (`track_rate.read_at_track_rate`)."""
        if claimed is None:
            return None
        from signatures.classify.verify import bands_from, verify
        from signatures.features import FEATURE_NAMES

        card_bands = getattr(classifier, "physics_bands", None)
        measured = {name: getattr(feats.features, name) for name in FEATURE_NAMES}  # asdict's deep copy: ~80 us
        estimates = {**measured, **feats.physics}
        if track_rate_hz is not None and feats.flash_curve is not None:
            from signatures.classify.track_rate import read_at_track_rate

            estimates.update(read_at_track_rate(estimates, feats.flash_curve, track_rate_hz))
        return verify(estimates, claimed, pred.probabilities,
                      rec.config.unambiguous_velocity_mps, known=pred.known, bands=bands_from(card_bands, claimed.slug),
                      calibration=getattr(classifier, "score_calibration", None),
                      also=[(p, bands_from(card_bands, p.slug)) for p in group],
                      alternatives=[(p, bands_from(card_bands, p.slug)) for p in alternatives])

    def _confusable_models(self, classifier: Classifier, model: str, tracks: bool = False) -> tuple[str, ...] | None:
        """The models registered (active) at this site that the bundle's card says radar cannot tell
        from the registered `model`: a site card's single-dwell pairs (or its track pairs when
        `tracks`), a shipped card's measured separation; None for a card that says neither. One
        query, only when the card lists a pair with `model`."""
        if not getattr(classifier, "site", False) and not getattr(classifier, "separation", None):
            return None
        others = classifier.confusable_with(model, tracks) if model else ()
        return tuple(sorted(set(others) & self.db.registered_models())) if others else ()

    @staticmethod
    def _group(others: tuple[str, ...] | None, auth: RemoteIdAuth,
               profile: Callable[[str], UavProfile | None]) -> tuple:
        """The profiles a claim is verified together with: where its DRIP signature is valid (the
        signature vouches for the exact identity), the registered models radar cannot tell from its
        own (`others`, at the level the check decides at), so that radar vouches for what it can
        tell; () otherwise. `profile`: a model's registered profile."""
        if auth.status != "valid" or not others:
            return ()
        return tuple(p for p in map(profile, others) if p is not None)

    def _front(self, rec: Recording, serial: str | None, file: str, digest: str, timer: _Timer,
               captured: bool = False, track: bool = False, heard: Broadcaster | None = None,
               sprt: Sprt | None = None, track_rate_hz: float | None = None) -> _Front:
        """Everything before the radar: the claim, the registry, DRIP, and the request of the policy
        with the radar not run (asked once per batch: `_early`).
        `captured`: the return's Remote ID was replaced by a capture's (`RidCapture.claims`), the
        messages of `heard` (its `remoteid.capture.Broadcaster`, None when nothing was heard)."""
        with timer.stage("remote_id"):
            claim = read_claim(rec, serial, capture=captured)
            if heard is not None:  # which transmitters sent it, and whether they conflict
                claim = replace(claim, transmitters=heard.senders, conflict=heard.conflict)
        with timer.stage("registry"):
            facts = RegistryFacts.of(self.db.identity(claim.serial))
        mid = rec.mid_time
        with timer.stage("remote_id_auth"):
            auth = authenticate(claim, facts, mid, self.trusted_registries)
        if auth.status == "valid":  # kinematics from signed Location messages only
            claim = claim.signed_only(auth.covered, rec.start_time, mid)
        evidence = Evidence(claim, facts, int(rec.start_time.timestamp()), _issues(claim, auth, mid, None), auth=auth,
                            range_measured=rec.domain != "cw", sprt=sprt or self.sprt)
        return _Front(rec, claim, auth, evidence, evidence.policy_input(), file, digest, timer, track, track_rate_hz)

    def _prepare(self, f: _Front, memo: _Memo) -> _Pending:
        """What the radar stages of a return the registry did not decide need: the bundle of its
        waveform, the registered model's physics and alternatives, the claim's own target.
        `memo`: the batch's answers so far (one bundle per waveform, one registry read per question)."""
        from authn.association import Association, applies
        from signatures.classify.inference import classifier_for
        from signatures.radar import recording_waveform

        classifier = memo(("bundle", recording_waveform(f.rec).key),  # the bundle of the file's waveform
                          lambda: classifier_for(f.rec, self.model, f.file or "FILE"))
        model, timer = f.evidence.registry.model, f.timer

        def profile(slug: str) -> UavProfile | None:
            return memo(("profile", slug), lambda: self.db.profile(slug))

        with timer.stage("registry"):  # the registered model's physics, only now that the radar runs
            claimed = profile(model) if model else None
            alternatives = tuple(p for p in memo(("active",), self.db.registered_profiles) if p.slug != model)
            single, over_tracks = (memo(("confusable", id(classifier), model, t),
                                        lambda t=t: self._confusable_models(classifier, model, tracks=t))
                                   for t in (False, True))
            evidence = replace(f.evidence, preset=classifier.preset, radar_confusable=_flag(single),
                               radar_confusable_track=_flag(over_tracks),
                               separation=classifier.separation_of(model) if model else {})
            group = self._group(over_tracks if f.track else single, f.auth, profile)
        expected = None  # at the first chirp, the time the radar's range estimate refers to
        if f.claim.state is not None:
            site = f.rec.site
            expected = expected_from_radar(f.claim.state, site.lat_deg, site.lon_deg, site.alt_m, f.rec.start_time)
        # the claim's own target (position, then velocity; CW: none, docs/format.md): chosen in the feature stage
        assoc = None if applies(f.rec, expected, f.claim.state) else Association(None)
        return _Pending(f, evidence, classifier, claimed, expected, assoc, group, alternatives)

    def _finish(self, p: _Pending, feats: FeatureResult, pred: Prediction | None) -> Evidence:
        """The evidence with the radar's findings from the features and the class, and kinematics."""
        rec, claim, cw = p.rec, p.front.claim, p.rec.domain == "cw"
        radar = RadarEvidence(gated=p.gate is not None, model_card_sha256=p.classifier.card_digest,
                              association=p.association)
        if feats.detected and pred is not None:
            radar = replace(radar, model=pred.label, confidence=round(pred.confidence, 4), known=pred.known,
                            range_m=None if cw else round(float(feats.range_m), 3),
                            radial_velocity_mps=round(float(feats.radial_velocity_mps), 4),
                            operational_state=pred.operational_state, used_cnn=pred.used_cnn, nearest=pred.nearest,
                            verification=self._verify(feats, pred, p.claimed, rec, p.classifier, p.group,
                                                      p.alternatives, p.front.track_rate_hz))
        kin = None
        if p.expected is not None and radar.detected:
            with p.timer.stage("kinematics"):  # CW: the range part is computed on the expected range, never shown
                res = residuals(p.expected, claim.state, p.expected.range_m if cw else radar.range_m,
                                radar.radial_velocity_mps, rec.config.range_bin_m(rec.n_samples),
                                rec.config.doppler_bin_mps(rec.n_chirps),
                                rec.config.measured_unambiguous_velocity_mps(rec.n_samples))
            kin = KinematicsEvidence(p.expected, res, range_measured=not cw)
        return replace(p.evidence, radar=radar, kinematics=kin,
                       remote_id_issues=_issues(claim, p.front.auth, rec.mid_time, radar.rotorcraft))

    # --- the runner: every check goes through decide, and check records before it returns --
    def check(self, items: Sequence[CheckInput], stop: Callable[[], bool] = lambda: False, *,
              idempotency_key: str | None = None, record_on_fault: bool = True) -> Batch:
        """Decide and record: the one way a check is made by the CLI (one file or many), the
        service and the cluster. The decisions and failures are appended to the audit log in
        one transaction before this returns, so nothing the caller emits is unaudited; a
        commit that fails raises. A SystemFault that stopped the batch is in `Batch.fault`
        (what was decided before it is recorded) or, with `record_on_fault=False` (a cluster
        partition that must be retried whole), raised before anything is recorded."""
        batch = self.decide(items, stop)
        if batch.fault is not None and not record_on_fault:
            raise batch.fault
        ids, ms = self._append(batch.items, idempotency_key)
        return replace(batch, items=[o.recorded(seq, ms) if isinstance(o, Outcome) else o
                                     for o, seq in zip(batch.items, ids)])

    def decide(self, items: Sequence[CheckInput], stop: Callable[[], bool] = lambda: False) -> Batch:
        """Decide many returns (no audit write), batched: the policy with the radar not run is one
        Cedar call for as many returns as memory holds, the returns that need the radar share one
        batched feature extraction (`signatures.features.extract_many`, grouped by waveform, as
        many cubes at once as `batch_size` allows in memory), one classifier call per bundle and
        one Cedar call for their decisions.
        Bad input or a crash in one return is that return's Failure; a SystemFault (database,
        policy engine) stops the batch (`Batch.fault`). Batched timings are each return's share.
        `stop()` is asked before each return is read: once true, the returns read so far are
        decided and the rest are left out of `Batch.items`. A SystemFault makes each return read
        and not yet decided a Failure."""
        from core.errors import SystemFault

        done: dict[Key, Outcome | Failure] = {}
        fronts: dict[Key, _Front] = {}
        targets: dict[int, tuple[list[dict[str, float]], float]] = {}  # capture input -> its targets, range bin
        rows = _Memo()  # rows per batch by cube shape: the available memory read once per call

        def flush() -> None:
            decided, undecided = self._early(fronts)
            done.update(decided)
            pending = self._prepared(undecided)
            done.update({k: v for k, v in pending.items() if isinstance(v, Failure)})
            done.update(self._radar_batch({k: v for k, v in pending.items() if isinstance(v, _Pending)}))
            fronts.clear()

        def stopped(exc: SystemFault, *after: Failure) -> Batch:
            """The batch stopped by `exc`: each return it left undecided is a Failure."""
            done.update({k: Failure.of(f.file, f.claim.serial, exc) for k, f in fronts.items() if k not in done})
            return Batch([done[j] for j in sorted(done)] + list(after), exc)

        for i, item in enumerate(items):
            if stop():
                items = items[:i]
                break
            try:
                for j, front in enumerate(self._fronts(item, i, targets)):
                    if isinstance(front, _Front):
                        fronts[(i, j)] = front
                    else:
                        done[(i, j)] = front
            except SystemFault as exc:  # what the policy decides without the radar is still decided
                try:
                    done.update(self._early(fronts)[0])
                except SystemFault:
                    pass
                return stopped(exc, Failure.of(item.name, item.serial, exc))
            last = next(reversed(fronts.values()), None)
            if last is not None and len(fronts) > 1 and len(fronts) >= rows(  # memory holds no more
                    (last.rec.n_chirps, last.rec.n_samples), partial(_batch_size, last.rec)):
                try:
                    flush()
                except SystemFault as exc:
                    return stopped(exc)
        try:
            flush()
        except SystemFault as exc:
            return stopped(exc)
        self._non_cooperative(done, targets)
        return Batch([done[j] for j in sorted(done)])

    def _fronts(self, item: CheckInput, i: int,
                targets: dict[int, tuple[list[dict[str, float]], float]]) -> list[_Front | Failure]:
        """Read one input and gather what comes before the radar: one front per claim (a capture
        names several drones, each its own decision); bad input or a crash is its Failure, a
        SystemFault propagates."""
        from core.errors import SystemFault

        try:
            timer = _Timer()
            with timer.stage("read"):
                rec, digest = item.load()
            if item.rid_capture is None:
                return [self._front(rec, item.serial, item.name, digest, timer, track=item.track, sprt=item.sprt,
                                    track_rate_hz=item.track_rate_hz)]
            with timer.stage("rid_capture"):  # one claim per drone heard: each its own decision (and audit entry)
                claims = item.rid_capture.claims(rec, item.serial)
            fronts = [self._front(r, s, item.name, digest, _Timer() if j else timer, captured=True, heard=b,
                                  sprt=item.sprt)
                      for j, (r, s, b) in enumerate(claims)]
            with timer.stage("non_cooperative"):
                targets[i] = self._targets(rec)
            shared = {k: v for k, v in timer.ms.items() if k in ("read", "rid_capture")}
            for f in fronts[1:]:  # the shared read is each claim's too
                f.timer.ms.update(shared)
            return list(fronts)
        except SystemFault:
            raise
        except Exception as exc:  # noqa: BLE001 - one bad or crashing return must not stop the batch
            return [Failure.of(item.name, item.serial, exc)]

    def _early(self, fronts: dict[Key, _Front]) -> tuple[dict[Key, Outcome], dict[Key, _Front]]:
        """The policy with the radar not run, one Cedar call for all `fronts`: (the Outcomes it
        already decides, the fronts that need the radar). A SystemFault propagates."""
        if not fronts:
            return {}, {}
        t0 = time.perf_counter()
        results = self.policy.decide_many_without_evidence([f.request for f in fronts.values()])
        _shares([f.timer for f in fronts.values()], "policy_registry", t0)
        decided = {k: Outcome.of(f.file, f.digest, r, f.evidence, f.timer, self.policy.sha256)
                   for (k, f), r in zip(fronts.items(), results) if r is not None}
        return decided, {k: f for k, f in fronts.items() if k not in decided}

    def _prepared(self, fronts: dict[Key, _Front]) -> dict[Key, _Pending | Failure]:
        """`_prepare` of each front: a SystemFault propagates, any other error is that return's Failure."""
        from core.errors import SystemFault

        out: dict[Key, _Pending | Failure] = {}
        memo = _Memo()
        for k, f in fronts.items():
            try:
                out[k] = self._prepare(f, memo)
            except SystemFault:
                raise
            except Exception as exc:  # noqa: BLE001 - one bad or crashing return must not stop the batch
                out[k] = Failure.of(f.file, f.claim.serial, exc)
        return out

    @staticmethod
    def _targets(rec: Recording) -> tuple[list[dict[str, float]], float]:
        """The return's radar targets (`signatures.features.detections`: none for CW) and its
        range bin in metres."""
        from signatures.features import detections

        found = [{"range_m": round(r, 3), "snr_db": round(snr, 1)} for r, snr in detections(rec)]
        return found, rec.config.range_bin_m(rec.n_samples)

    @staticmethod
    def _non_cooperative(done: dict[Key, Outcome | Failure],
                         targets: dict[int, tuple[list[dict[str, float]], float]]) -> None:
        """Report, on every decision of a return checked with a capture, its targets that no claim
        explains: none whose declared position matched the radar (range residual within
        tolerance) at that target (its radar range within 3 range bins of it)."""
        def explains(o: Outcome, target: dict[str, float], bin_m: float) -> bool:
            kin, radar = o.evidence.kinematics, o.radar
            return (kin is not None and radar is not None and radar.range_m is not None
                    and kin.residuals.range_residual_m <= kin.residuals.range_tolerance_m
                    and abs(radar.range_m - target["range_m"]) <= 3 * bin_m)

        for i, (found, bin_m) in targets.items():
            outs = {k: o for k, o in done.items() if k[0] == i and isinstance(o, Outcome)}
            silent = [t for t in found if not any(explains(o, t, bin_m) for o in outs.values())]
            done.update({k: o.with_non_cooperative(silent) for k, o in outs.items()})

    def decide_one(self, item: CheckInput) -> Outcome:
        """One decision, not recorded (benchmarks, tests); raises what stopped it."""
        batch = self.decide([item])
        if batch.fault is not None:
            raise batch.fault
        result = batch.items[0]
        if isinstance(result, Failure):
            if result.exc is not None:
                raise result.exc
            result.raise_()
        return result  # type: ignore[return-value]

    def evaluate(self, path: str | Path, serial: str | None = None) -> Outcome:
        """Decide one file, not recorded (benchmarks, tests)."""
        return self.decide_one(CheckInput.file(path, serial))

    def evaluate_recording(self, rec: Recording, serial: str | None = None, file: str = "",
                           digest: str = "") -> Outcome:
        """Decide an in-memory recording, not recorded (benchmarks and the stress suite skip the file)."""
        return self.decide_one(CheckInput.recording(rec, serial, file, digest))

    @staticmethod
    def _features_or_failure(p: _Pending, expected: float | Chooser | None) -> FeatureResult | Failure:
        from signatures.features import extract

        try:
            return extract(p.rec, expected_range_m=expected)
        except Exception as exc:  # noqa: BLE001 - this file's failure, not the batch's
            return Failure.of(p.front.file, p.front.claim.serial, exc)

    def _features(self, pending: dict[Key, _Pending]) -> tuple[dict[Key, FeatureResult], dict[Key, Failure]]:
        """Every pending return's features in one batch (each its share of the time), the claim's
        target associated on the way (`pending` gets each association); where the batch fails,
        each return on its own, to find the file at fault."""
        keys = list(pending)
        chosen: dict[Key, Association] = {}
        expected = [pending[k].expected_range(chosen, k) for k in keys]
        t0 = time.perf_counter()
        try:
            if len(keys) == 1:  # one return: a batch of one on numpy's FFT (no scipy import)
                from signatures.features import extract

                feats: list[FeatureResult | Failure] = [extract(pending[keys[0]].rec, expected_range_m=expected[0])]
            else:
                from signatures.features import extract_many

                feats = list(extract_many([pending[k].rec for k in keys], expected))
        except Exception:  # noqa: BLE001 - find the file at fault: each return on its own
            feats = [self._features_or_failure(pending[k], e) for k, e in zip(keys, expected)]
        pending.update({k: replace(pending[k], association=a) for k, a in chosen.items()})
        found = {k: f for k, f in zip(keys, feats) if not isinstance(f, Failure)}
        associated = sum(pending[k].timer.ms.get("associate", 0.0) for k in chosen)
        _shares([pending[k].timer for k in found], "radar_features", t0, less_ms=associated)
        return found, {k: f for k, f in zip(keys, feats) if isinstance(f, Failure)}

    @staticmethod
    def _classes(pending: dict[Key, _Pending], fmap: dict[Key, FeatureResult],
                 failed: dict[Key, Failure]) -> dict[Key, Prediction]:
        """One classifier call per bundle over the returns where a target was detected; a broken
        bundle fails its returns (into `failed`), not the batch."""
        import numpy as np

        by_bundle: dict[int, list[Key]] = {}
        for k, f in fmap.items():
            if f.detected:
                by_bundle.setdefault(id(pending[k].classifier), []).append(k)
        preds: dict[Key, Prediction] = {}
        for ks in by_bundle.values():
            t0 = time.perf_counter()
            clf = pending[ks[0]].classifier
            try:
                rows = clf.predict_many(np.stack([fmap[k].as_array() for k in ks]),
                                        lambda ks=ks: np.stack([fmap[k].rd_patch for k in ks]),
                                        # a bundle serves a band of carriers: its Hz features are rescaled
                                        np.array([pending[k].rec.config.carrier_hz for k in ks]))
            except Exception as exc:  # noqa: BLE001 - a broken bundle fails its returns, not the batch
                failed.update({k: Failure.of(pending[k].front.file, pending[k].front.claim.serial, exc) for k in ks})
                continue
            _shares([pending[k].timer for k in ks], "classify", t0)
            preds.update(zip(ks, rows))
        return preds

    def _radar_batch(self, pending: dict[Key, _Pending]) -> dict[Key, Outcome | Failure]:
        """Features of every pending return in batches, classes per bundle, each return's evidence,
        then one Cedar call for all their decisions."""
        from core.errors import SystemFault

        if not pending:
            return {}
        with signing_warmed():  # the audit's cryptography imported while the radar runs
            fmap, failed = self._features(pending)
            preds = self._classes(pending, fmap, failed)
        out: dict[Key, Outcome | Failure] = dict(failed)
        finished: dict[Key, Evidence] = {}
        for k, feats in fmap.items():
            if k in failed:
                continue
            try:
                finished[k] = self._finish(pending[k], feats, preds.get(k))
            except SystemFault:
                raise
            except Exception as exc:  # noqa: BLE001
                out[k] = Failure.of(pending[k].front.file, pending[k].front.claim.serial, exc)
        t0 = time.perf_counter()
        results = self.policy.decide_many([ev.policy_input() for ev in finished.values()])
        _shares([pending[k].timer for k in finished], "policy", t0)
        for (k, ev), result in zip(finished.items(), results):
            f = pending[k].front
            out[k] = Outcome.of(f.file, f.digest, result, ev, f.timer, self.policy.sha256)
        return out

    def record(self, outcomes: Sequence[Outcome | Failure], idempotency_key: str | None = None) -> list[int]:
        """Append decisions and failed checks in one transaction; raises DatabaseFault if it
        does not commit (the caller then prints no decision). With `idempotency_key`, a key
        that already committed writes nothing and returns that transaction's entry ids."""
        return self._append(outcomes, idempotency_key)[0]

    def _append(self, outcomes: Sequence[Outcome | Failure], idempotency_key: str | None) -> tuple[list[int], float]:
        """`record`: (the entry ids, the audit's ms per entry)."""
        entries = [AuditLog.decision(o.serial, o.decision, o.audit_payload()) if isinstance(o, Outcome)
                   else o.entry(self.policy.sha256) for o in outcomes]
        t0 = time.perf_counter()
        written = AuditLog(self.db, self.policy.text).record(entries, idempotency_key=idempotency_key)
        return [e.seq for e in written], round((time.perf_counter() - t0) * 1e3 / max(len(entries), 1), 3)
