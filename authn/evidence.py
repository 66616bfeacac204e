"""The evidence of one check, as one typed object.

Built once per check (claim, registry facts, radar, kinematics, Remote ID issues); the
Cedar request, the JSON output and the audit payload are all derived from it, so each fact
is named in one place. Cedar wants integers, hence the centimetre and basis-point views.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from datetime import datetime, timezone
from typing import TYPE_CHECKING, Any

from core.errors import AuthnError
from core.uasid import SerialError, as_heard, normalise
from authn.kinematics import DeclaredState, Expected, Residuals

if TYPE_CHECKING:
    from registry.dbapi import IdentityFacts

__all__ = ["Claim", "RegistryFacts", "RemoteIdAuth", "RadarEvidence", "KinematicsEvidence", "Evidence", "authenticate",
           "read_claim"]

#: Cedar integers are 64-bit; a residual is capped well inside them
_MAX_CEDAR_CM = 2**53
#: What the JSON says where a CW recording (docs/format.md, `domain`) left the range unmeasured
RANGE_NOT_MEASURED = "not measured: CW recording"
#: What the claim's JSON says where no Remote ID Location declared a position (`claim.position`)
POSITION_NOT_CHECKED = "not checked: no Remote ID position"


@dataclass(frozen=True)
class Claim:
    """Who the drone says it is, and what its Remote ID declares."""

    serial: str
    source: str  # "cli" | "remote_id"
    rid_serial: str | None = None
    ua_type: int | None = None
    state: DeclaredState | None = None
    n_messages: int = 0
    #: every single message as (decoded, its 25 wire bytes): what DRIP verification reads
    wire: tuple[tuple[Any, bytes], ...] = ()
    #: when a sniffer heard each message of `wire` (s after the dwell's start), for a claim from a
    #: capture (`--rid-capture`): the time of record of its Locations; empty otherwise
    heard_s: tuple[float, ...] = ()
    #: the check was given a capture: a claim with no Remote ID in it is rejected (`no-remote-id`)
    capture: bool = False
    #: a capture's transmitters (Wi-Fi source addresses, BLE addresses) that sent this claim's messages
    transmitters: tuple[str, ...] = ()
    #: conflicting transmitters (`remoteid.capture.Broadcaster.conflict`): each with the UAS IDs it sent
    conflict: tuple[tuple[str, tuple[str, ...]], ...] = ()

    @property
    def rests_on_remote_id(self) -> bool:
        """The claimed identity is the Remote ID's (no --serial), or a capture's messages name it: then
        a Location must say where the drone is (`remote-id-no-location`)."""
        return self.source == "remote_id" or (self.capture and self.n_messages > 0)

    def to_json(self) -> dict[str, Any]:
        doc: dict[str, Any] = {"serial": self.serial, "source": self.source, "remote_id_serial": self.rid_serial}
        if self.state is None:  # nothing to compare with the radar: the position is not checked
            doc["position"] = POSITION_NOT_CHECKED
        return doc

    def capture_json(self) -> dict[str, Any]:
        """A capture's claim: the transmitters it was heard from, and their conflict if any."""
        if not self.capture:
            return {}
        doc: dict[str, Any] = {"transmitters": list(self.transmitters)}
        if self.conflict:
            doc["conflict"] = [{"transmitter": t, "serials": list(ids)} for t, ids in self.conflict]
        return doc

    def signed_only(self, covered: tuple[int, ...], reference: datetime, mid: datetime) -> "Claim":
        """The same claim with the declared state taken only from Location messages that a
        verified signature covers (none covered: no declared state, hence no kinematics)."""
        idx = [i for i in covered if i < len(self.wire)]
        heard = [self.heard_s[i] for i in idx] if self.heard_s else None
        return replace(self, state=_nearest_state([self.wire[i][0] for i in idx], reference, mid, heard))


def _nearest_state(messages: list[Any], reference: datetime, mid: datetime,
                   heard_s: list[float] | None = None) -> DeclaredState | None:
    """The declared state of the Location message nearest the middle of the dwell. With
    `heard_s` (a capture's reception times, s after `reference`) a Location's time is when the
    sniffer heard it, not the tenth-of-hour timestamp the drone wrote (docs/remoteid.md)."""
    from datetime import timedelta

    from remoteid import Location

    states = []
    for i, m in enumerate(messages):
        s = DeclaredState.from_location(m, reference) if isinstance(m, Location) else None
        if s is not None and heard_s is not None:
            s = replace(s, time=reference + timedelta(seconds=heard_s[i]))
        if s is not None:
            states.append(s)
    return min(states, key=lambda s: abs((s.time - mid).total_seconds()) if s.time else 1e9, default=None)


def read_claim(rec: Any, serial: str | None, capture: bool = False) -> Claim:
    """The claimed serial (--serial wins) and what the Remote ID messages declare. Messages from
    a capture (`rec.remote_id_source == "capture"`: `--rid-capture`, or written by `authn import
    --rid-capture`) have `remote_id_time_s`, when the sniffer heard each, as their time of record.
    `capture`: the check was given a capture (its absence of messages is evidence)."""
    from remoteid import BasicId
    from remoteid.codec import decode_rows_raw

    wire = tuple(decode_rows_raw(rec.remote_id)) if rec.remote_id is not None else ()
    msgs = [m for m, _ in wire]
    times = rec.remote_id_time_s
    heard = getattr(rec, "remote_id_source", None) == "capture" and times is not None and len(times) == len(wire)
    heard_s = tuple(float(t) for t in times) if heard else ()
    basic = next((m for m in msgs if isinstance(m, BasicId) and m.uas_id), None)
    rid_serial = as_heard(basic.uas_id) if basic else None
    if serial is None and rid_serial is None:
        raise AuthnError("no claim: give --serial, or a file whose Remote ID carries a Basic ID serial")
    if serial is not None:
        try:
            serial = normalise(serial)
        except SerialError as exc:
            raise AuthnError(f"--serial: {exc}") from None
    return Claim(serial=serial or rid_serial, source="cli" if serial else "remote_id", rid_serial=rid_serial,
                 ua_type=basic.ua_type if basic else None,
                 state=_nearest_state(msgs, rec.start_time, rec.mid_time, list(heard_s) if heard_s else None),
                 n_messages=len(msgs), wire=wire, heard_s=heard_s, capture=capture)


def authenticate(claim: Claim, facts: "RegistryFacts", dwell_time: datetime,
                 trusted_registries: dict[bytes, bytes] | None = None) -> "RemoteIdAuth":
    """DRIP verification of the claim's Remote ID.

    The signer's key is the one the registry holds for the claimed identity (a DET signs only
    if it is the DET of that key: RFC 9374's binding), or one a DRIP Link from a trusted
    registry (HDA DET -> key) vouches for. A valid signature counts only if its DET is the
    claimed identity's: the DET of its registered key, or the DET in its DRIP session ID;
    else the status is `unknown-key` (signed, but by someone else)."""
    from remoteid import AuthPage, AuthPage0

    if not any(isinstance(m, (AuthPage0, AuthPage)) for m, _ in claim.wire):
        return RemoteIdAuth()  # absent: cryptography is not even imported
    from remoteid.drip import det_matches_key, verify

    def key_for(det: bytes) -> bytes | None:
        key = facts.public_key
        return key if key is not None and det_matches_key(det, key) else None

    result = verify(claim.wire, key_for, dwell_time, trusted_registry_keys=trusted_registries or {})
    if result.status == "valid" and not _is_claimed(result.det, claim, facts):
        return RemoteIdAuth("unknown-key", f"signed by DET {result.det}, which is not the claimed identity's",
                            tuple(result.sam_types), (), result.det)
    return RemoteIdAuth(result.status, result.reason, tuple(result.sam_types), tuple(result.covered), result.det)


def _is_claimed(det_hex: str | None, claim: Claim, facts: "RegistryFacts") -> bool:
    from remoteid.drip import det_matches_key

    if det_hex is None:
        return False
    det = bytes.fromhex(det_hex)
    if facts.public_key is not None and det_matches_key(det, facts.public_key):
        return True
    return claim.serial.upper() == ("01" + det_hex).upper()  # a DRIP session ID names its DET


def _epoch(when: datetime) -> int:
    return int(when.timestamp())


@dataclass(frozen=True)
class RegistryFacts:
    """The claimed identity as the registry holds it (`registry.dbapi.IdentityFacts`, the one
    model of an identity a decision reads), or its absence: an unregistered serial is a fact too."""

    identity: IdentityFacts | None = None

    @classmethod
    def of(cls, identity: IdentityFacts | None) -> "RegistryFacts":
        return cls(identity)

    @property
    def registered(self) -> bool:
        return self.identity is not None

    @property
    def status(self) -> str:
        return self.identity.status if self.identity is not None else "unregistered"

    @property
    def model(self) -> str:
        return self.identity.model if self.identity is not None else ""

    @property
    def id_type(self) -> str:
        return self.identity.id_type if self.identity is not None else ""

    @property
    def valid_from(self) -> datetime | None:
        return self.identity.valid_from if self.identity is not None else None

    @property
    def valid_until(self) -> datetime | None:
        return self.identity.valid_until if self.identity is not None else None

    @property
    def public_key(self) -> bytes | None:
        return self.identity.public_key if self.identity is not None else None

    def principal(self) -> dict[str, Any]:
        """Cedar attributes of the principal `Uav::"<serial>"`."""
        attrs: dict[str, Any] = {"registered": self.registered, "status": self.status, "model": self.model,
                                 "id_type": self.id_type,
                                 "valid_from_s": _epoch(self.valid_from) if self.valid_from else 0,
                                 "has_key": self.public_key is not None}
        if self.valid_until is not None:
            attrs["valid_until_s"] = _epoch(self.valid_until)
        return attrs

    def to_json(self) -> dict[str, Any]:
        return {"registered": self.registered, "status": self.status, "model": self.model or None,
                "has_key": self.public_key is not None,
                "valid_from": self.valid_from.isoformat() if self.valid_from else None,
                "valid_until": self.valid_until.isoformat() if self.valid_until else None}


@dataclass(frozen=True)
class RemoteIdAuth:
    """What the DRIP authentication of the Remote ID messages came to (RFC 9575)."""

    status: str = "absent"  # valid | invalid | absent | unknown-key | expired | not-yet-valid
    reason: str | None = None
    sam_types: tuple[str, ...] = ()
    covered: tuple[int, ...] = ()  # indices (in the decoded message list) that a valid signature covers
    det: str | None = None

    def to_json(self) -> dict[str, Any]:
        return {"status": self.status, "reason": self.reason, "sam_types": list(self.sam_types),
                "covered_messages": list(self.covered), "det": self.det}


@dataclass(frozen=True)
class RadarEvidence:
    """What the radar stages found: a target (or none), its class and where it is."""

    gated: bool
    model: str = "none"
    confidence: float | None = None
    known: bool = True
    range_m: float | None = None
    radial_velocity_mps: float | None = None
    used_cnn: bool = False
    operational_state: str | None = None
    nearest: str | None = None
    model_card_sha256: str | None = None
    #: 1:1 verification against the claimed profile (`signatures.classify.verify`); None when not run
    verification: Any = None
    #: how the claim's own target was chosen among the window's (`authn.association`); None: not run
    association: Any = None

    @property
    def detected(self) -> bool:
        return self.model != "none"

    @property
    def rotorcraft(self) -> bool:
        return self.model not in ("none", "bird", "unknown")

    def to_json(self) -> dict[str, Any]:
        doc: dict[str, Any] = {"model": self.model, "confidence": self.confidence, "known": self.known,
                               "range_m": self.range_m, "radial_velocity_mps": self.radial_velocity_mps,
                               "gated": self.gated, "used_cnn": self.used_cnn}
        if self.confidence is not None:  # a classified target
            doc.update(operational_state=self.operational_state, nearest=self.nearest)
        if self.verification is not None:
            doc["verification"] = self.verification.to_json()
        if self.association is not None:
            doc["target"] = self.association.to_json()
        return doc


def _rounded(x: float | None, digits: int) -> float | None:
    return None if x is None else round(x, digits)


def _cm(x: float) -> int:
    return int(min(round(x * 100.0), _MAX_CEDAR_CM))


@dataclass(frozen=True)
class KinematicsEvidence:
    """The declared state against the radar's range and radial velocity."""

    expected: Expected
    residuals: Residuals
    #: False for a CW recording: the range residual is not computed (only the velocity's is)
    range_measured: bool = True

    def context(self) -> dict[str, Any]:
        res = self.residuals
        ctx: dict[str, Any] = {"has_kinematics": True}
        if self.range_measured:
            ctx.update(range_residual_cm=_cm(res.range_residual_m), range_tolerance_cm=_cm(res.range_tolerance_m))
        if res.radial_velocity_residual_mps is not None:
            ctx.update(velocity_residual_cmps=_cm(res.radial_velocity_residual_mps),
                       velocity_tolerance_cmps=_cm(res.radial_velocity_tolerance_mps))
        return ctx

    def to_json(self) -> dict[str, Any]:
        res = self.residuals
        doc: dict[str, Any] = {
            "expected_range_m": round(self.expected.range_m, 3),
            "expected_radial_velocity_mps": _rounded(self.expected.radial_velocity_mps, 4),
            "range_residual_m": round(res.range_residual_m, 3) if self.range_measured else None,
            "range_tolerance_m": round(res.range_tolerance_m, 3) if self.range_measured else None,
            "radial_velocity_residual_mps": _rounded(res.radial_velocity_residual_mps, 4),
            "radial_velocity_tolerance_mps": _rounded(res.radial_velocity_tolerance_mps, 4)}
        if not self.range_measured:
            doc["range_evidence"] = RANGE_NOT_MEASURED
        return doc


@dataclass(frozen=True)
class Evidence:
    """Everything one check gathered; `radar` is None while (or because) the radar did not run.
    Frozen: each stage that learns more builds a new value (`dataclasses.replace`)."""

    claim: Claim
    registry: RegistryFacts
    time_s: int
    remote_id_issues: list[str]
    preset: str = ""
    auth: RemoteIdAuth = RemoteIdAuth()
    radar: RadarEvidence | None = None
    kinematics: KinematicsEvidence | None = None
    #: False when the recording cannot measure range (a CW radar): no range evidence at all
    range_measured: bool = True
    #: a site bundle decided: whether the registered model is radar-confusable with another model
    #: registered at the site (its enrolment card's pairs); None for any other bundle
    radar_confusable: bool | None = None
    #: the same by the card's track-level pairwise errors: what a track decision puts in its place
    #: (`authn.track`, docs/enrolment.md); None for any other bundle
    radar_confusable_track: bool | None = None

    #: the sequential test the radar's evidence is put to (`authn.sprt.Sprt`; None: its defaults)
    sprt: Any = None
    #: the bundle card's measured separation of the claimed model from each alternative: the mean
    #: per-dwell increment of a genuine claim against it (`Classifier.separation`); {}: not measured
    separation: dict[str, float] | None = None

    def test(self) -> Any:
        """The sequential test of this check (`authn.sprt.Sprt`)."""
        if self.sprt is None:
            from authn.sprt import Sprt

            return Sprt()
        return self.sprt

    def increments(self, sprt: Any = None) -> list[dict[str, float]]:
        """This dwell's increments per alternative (`Sprt.increments` of `sprt`, default this check's:
        capped; where the physics term abstained, only what counts against the claim); [] where
        nothing was verified. An LLR that is no number counts fully against the claim."""
        v = self.radar.verification if self.radar is not None else None
        if v is None or not v.terms:
            return []
        from signatures.classify.verify import UNKNOWN

        return [(sprt or self.test()).increments(v.against or {UNKNOWN: v.llr}, not v.physics_abstained)]

    def to_decide(self, increments: list[dict[str, float]] | None = None) -> dict[str, Any]:
        """What would decide an inconclusive claim: about how many more dwells, and whether a valid
        DRIP signature would (the radar favours the claim: the policy then accepts). Where the radar
        favours the claim the dwells come from the card's measured separation of a genuine claim from
        its closest alternative (else this evidence's own mean increment); where it is against the
        claim, from this evidence's own mean increment toward the reject bound. `increments`: a
        track's, per dwell (default: this dwell's)."""
        sprt = self.test()
        incs = self.increments() if increments is None else increments
        record = sprt.record(incs)
        llr, refute = record["llr_cn"] / 100.0, record["refute_llr_cn"] / 100.0
        from authn.sprt import alternative_sums, observations

        v = self.radar.verification if self.radar is not None else None
        raw = v.against if v is not None else {}
        sums = alternative_sums(incs)
        # the least capped sum; among ties the least uncapped LLR (the verification's own `closest`)
        closest = min(sums, key=lambda k: (sums[k], raw.get(k, 0.0))) if sums else None
        seen = observations(incs)
        own = sums[closest] / seen if closest and seen else None
        # evidence for the claim goes on at a genuine claim's measured pace; evidence against, at its own
        measured = (self.separation or {}).get(closest) if closest and llr > 0 else None
        step = measured if measured is not None else own
        start = llr if step is not None and step > 0 else refute  # accepting reads the least, refuting the mixture
        more = sprt.dwells_to_decide(step, start, seen) if step is not None else None
        doc: dict[str, Any] = {"llr_nats": round(llr, 4), "refute_llr_nats": round(refute, 4),
                               "accept_nats": round(record["accept_cn"] / 100.0, 2),
                               "reject_nats": round(record["reject_cn"] / 100.0, 2), "dwells": len(incs),
                               "closest": closest,
                               "separation_nats_per_dwell": None if step is None else round(step, 4),
                               "separation_from": None if step is None else ("card" if measured is not None
                                                                            else "these dwells"),
                               "more_dwells": more,
                               "signature": bool(incs) and llr > 0 and self.auth.status != "valid"}
        return doc

    # --- the Cedar request -----------------------------------------------------------
    def principal(self) -> dict[str, Any]:
        return self.registry.principal()

    def resource(self) -> dict[str, Any]:
        return {"time_s": self.time_s, "preset": self.preset}

    def context(self) -> dict[str, Any]:
        radar = self.radar
        ctx: dict[str, Any] = {
            "claim_source": self.claim.source, "radar_run": radar is not None,
            "target_detected": radar is not None and radar.detected,
            "radar_model": radar.model if radar is not None else "",
            "radar_known": bool(radar.known) if radar is not None else False,
            "radar_confidence_bp": int(round((radar.confidence or 0.0) * 10000)) if radar is not None else 0,
            "has_kinematics": False, "range_residual_cm": 0, "range_tolerance_cm": 0,
            "velocity_residual_cmps": 0, "velocity_tolerance_cmps": 0,
            "remote_id_present": self.claim.n_messages > 0, "remote_id_issues": list(self.remote_id_issues),
            "remote_id_auth": self.auth.status, "range_measured": self.range_measured}
        if self.claim.capture:  # only with --rid-capture: the request of any other check is unchanged
            ctx["remote_id_expected"] = True
        if self.claim.conflict:  # only where a capture's transmitters conflict (remote-id-conflict)
            ctx["remote_id_conflict"] = True
        if self.claim.rests_on_remote_id and self.claim.state is None:  # only then (remote-id-no-location)
            ctx["remote_id_no_location"] = True
        if self.radar_confusable is not None:  # only with a site bundle (authn models enrol)
            ctx["radar_confusable"] = self.radar_confusable
        if radar is not None and radar.detected:  # one dwell is a track of one: the same record, one rule
            ctx["track"] = self.test().record(self.increments())
        if radar is not None and radar.association is not None and radar.association.in_view is not None:
            ctx["targets_in_view"] = radar.association.in_view  # no-radar-target against no-target
        if self.kinematics is not None:
            ctx.update(self.kinematics.context())
        return ctx

    def policy_input(self) -> dict[str, Any]:
        """The exact request, as the audit keeps it for `authn audit replay`."""
        return {"serial": self.claim.serial, "principal": self.principal(), "resource": self.resource(),
                "context": self.context()}

    # --- the report ------------------------------------------------------------------
    def report(self) -> dict[str, Any]:
        """The evidence part of `authn check --json` (and of the audit payload)."""
        return {"dwell_start": datetime.fromtimestamp(self.time_s, timezone.utc).isoformat(),
                "claim": self.claim.to_json(), "registry": self.registry.to_json(),
                "radar": None if self.radar is None else self._radar_json(self.radar),
                "kinematics": None if self.kinematics is None else self.kinematics.to_json(),
                "remote_id": {"messages": self.claim.n_messages, "ua_type": self.claim.ua_type,
                              "issues": list(self.remote_id_issues), **self.claim.capture_json()},
                "remote_id_auth": self.auth.to_json()}

    def _radar_json(self, radar: RadarEvidence) -> dict[str, Any]:
        doc = radar.to_json()
        if self.separation:  # the card's measured separation of the claim from each alternative
            doc["separation_nats_per_dwell"] = {k: round(v, 3) for k, v in sorted(self.separation.items())}
        if not self.range_measured:
            doc["range_evidence"] = RANGE_NOT_MEASURED
        return doc

