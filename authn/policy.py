"""Cedar policy evaluation: the policy set is data, `cedarpy` is the engine.

The policy text and its schema are parsed and validated once (`PolicyEngine.load`),
then every request reuses the parsed handles. Reasons are the `@id` annotations of
the policies that determined the decision.

Skipping the radar: at load, every `forbid` policy whose conditions read no `context`
attribute the radar can change (only `PRE_RADAR_CONTEXT`: the claim's source, whether
Remote ID is present, its DRIP authentication, whether it declares a position, conflicting
transmitters) is found from the policy AST. When one of
those is satisfied before the radar runs, the deny holds whatever evidence the radar
could add (forbid overrides permit), so the decision over the registry and Remote ID
evidence is final. This needs one ordinary
`is_authorized` call; Cedar's partial evaluation, which answers the same question, is an
experimental cedarpy API (not for final decisions, by its own docs) and costs ~0.5 ms.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from authn.cedarpy_tree import defer
from core.errors import AuthnError, SystemFault

defer()  # cedarpy's policy-tree module, which deciding never reads, imported only if read
import cedarpy  # noqa: E402 - after defer()

ACTION = {"type": "Action", "id": "authenticate"}
SITE_ID = "site"
#: Context attributes known before the radar runs (a forbid reading only these can end a
#: check early). `remote_id_issues` is not one: the radar adds `not-rotorcraft`.
PRE_RADAR_CONTEXT = frozenset({"claim_source", "remote_id_present", "remote_id_auth", "remote_id_no_location",
                               "remote_id_conflict"})
#: Reason reported when a policy's condition raised an evaluation error (the claim is rejected).
POLICY_ERROR = "policy-error"


class PolicyError(AuthnError):
    """A policy file that cannot be read, parsed or validated against the schema."""


#: The decision where every forbid that fired says `@outcome("inconclusive")`: the evidence has not
#: decided (never an accept; docs/policies.md).
INCONCLUSIVE = "inconclusive"
#: What a forbid's `@outcome` annotation may say (absent: "reject").
OUTCOMES = frozenset({"reject", INCONCLUSIVE})


def policy_input(serial: str, principal: dict[str, Any], resource: dict[str, Any],
                 context: dict[str, Any]) -> dict[str, Any]:
    """One request as the audit keeps it (`policy_input`, what `authn audit replay` re-runs)."""
    return {"serial": serial, "principal": principal, "resource": resource, "context": context}


@dataclass(frozen=True)
class PolicyResult:
    decision: str  # "accept" | "reject" | "inconclusive"
    reasons: list[str]
    errors: list[str] = field(default_factory=list)
    #: the request Cedar evaluated (`policy_input`), the very value sent: the audit keeps it for replay
    request: dict[str, Any] = field(default_factory=dict, compare=False)


#: the shipped policy set and schema (package data beside this module: read as files, not through
#: importlib.resources, whose import costs a cold check ~5 ms)
SHIPPED_POLICIES = Path(__file__).with_name("policies")


def _shipped(name: str) -> str:
    return (SHIPPED_POLICIES / name).read_text(encoding="utf-8")


def _one_line(text: object) -> str:
    return " ".join(str(text).split())


@dataclass(frozen=True)
class PolicyEngine:
    """A validated policy set and schema, parsed once."""

    text: str
    sha256: str
    source: str
    policy_set: Any
    schema: Any
    effects: dict[str, str]  # policy id (parser's) -> "permit" | "forbid"
    context_free_forbids: frozenset[str]  # forbids that read no context the radar can change
    inconclusive_forbids: frozenset[str] = frozenset()  # forbids annotated @outcome("inconclusive")
    #: no policy names a RadarSite entity: one Cedar call may evaluate many requests, each with
    #: its own site entity (`decide_many`)
    batchable: bool = True

    @classmethod
    def load(cls, path: str | Path | None = None) -> "PolicyEngine":
        """The shipped default policy, or a file that replaces it (validated against the schema)."""
        if path is None:
            return cls.from_text(_shipped("default.cedar"), "default")
        try:
            text = Path(path).read_text()
        except (OSError, UnicodeDecodeError) as exc:
            raise PolicyError(f"{path}: cannot read policy file ({exc})") from None
        return cls.from_text(text, str(path))

    @classmethod
    def from_text(cls, text: str, source: str = "text") -> "PolicyEngine":
        """A policy set from its text (a file's, or one kept in the audit log for replay)."""
        schema_text = _shipped("schema.cedarschema")
        result = cedarpy.validate_policies(text, schema_text)
        if not result.validation_passed:
            first = result.errors[0] if result.errors else "invalid policy"
            raise PolicyError(f"{source}: policy does not validate against the schema: {_one_line(first)}")
        try:
            policy_set = cedarpy.PolicySet.from_str(text)
            schema = cedarpy.Schema.from_str(schema_text)
        except ValueError as exc:
            raise PolicyError(f"{source}: {_one_line(exc)}") from None
        parsed = json.loads(cedarpy.policies_to_json_str(text))
        static = parsed.get("staticPolicies", {})
        effects = {pid: body["effect"] for pid, body in static.items()}
        context_free = frozenset(pid for pid, body in static.items()
                                 if body["effect"] == "forbid" and _context_read(body) <= PRE_RADAR_CONTEXT)
        outcomes = {pid: (body.get("annotations") or {}).get("outcome", "reject") for pid, body in static.items()}
        for pid, outcome in outcomes.items():
            if outcome not in OUTCOMES or (outcome != "reject" and effects[pid] != "forbid"):
                name = (static[pid].get("annotations") or {}).get("id", pid)
                raise PolicyError(f"{source}: policy {name}: @outcome({outcome!r}) is not one of "
                                  f"{sorted(OUTCOMES)} on a forbid")
        digest = hashlib.sha256(text.encode()).hexdigest()
        return cls(text=text, sha256=digest, source=source, policy_set=policy_set, schema=schema,
                   effects=effects, context_free_forbids=context_free,
                   inconclusive_forbids=frozenset(p for p, o in outcomes.items() if o == INCONCLUSIVE),
                   batchable=not _names_site(parsed))

    # --- requests -----------------------------------------------------------------

    def _reasons(self, diag: Any, effect: str) -> list[str]:
        """The @id names of the satisfied policies with this effect (parser ids without one)."""
        ids = diag.id_annotations_by_reason
        return sorted(ids.get(r, r) for r in diag.reasons if self.effects.get(r) == effect)

    def _authorize(self, request: dict[str, Any]) -> Any:
        """One Cedar request; an exception from the engine itself is a system fault (exit 3)."""
        uav = {"type": "Uav", "id": request["serial"]}
        site = {"type": "RadarSite", "id": SITE_ID}
        return self._cedar([{"principal": uav, "action": ACTION, "resource": site, "context": request["context"]}],
                           [{"uid": uav, "attrs": request["principal"], "parents": []},
                            {"uid": site, "attrs": request["resource"], "parents": []}])[0]

    def _cedar(self, requests: list[dict[str, Any]], entities: list[dict[str, Any]]) -> list[Any]:
        """Cedar's answers, one `is_authorized` call for one request, one batch call for many."""
        try:
            if len(requests) == 1:
                return [cedarpy.is_authorized(requests[0], self.policy_set, entities, schema=self.schema)]
            return cedarpy.is_authorized_batch(requests, self.policy_set, entities, schema=self.schema)
        except Exception as exc:  # noqa: BLE001 - cedarpy raises plain exceptions of several kinds
            raise SystemFault(f"policy engine: {_one_line(exc)}") from None

    def _authorize_many(self, requests: Sequence[dict[str, Any]]) -> list[Any]:
        """Cedar's answers to many requests, in one call where the policies allow it: each request
        gets its own site entity (`site#i`, which no policy can tell apart: `batchable`) and the
        claimed UAV's, shared by requests with the same facts. A request whose evaluation erred is
        asked again alone, so that its error text names the entities as a single check's does."""
        if len(requests) <= 1 or not self.batchable:
            return [self._authorize(r) for r in requests]
        entities: dict[tuple[str, str], dict[str, Any]] = {}
        asked = []
        for i, r in enumerate(requests):
            uav, site = {"type": "Uav", "id": r["serial"]}, {"type": "RadarSite", "id": f"{SITE_ID}#{i}"}
            known = entities.setdefault(("Uav", r["serial"]), {"uid": uav, "attrs": r["principal"], "parents": []})
            if known["attrs"] != r["principal"]:  # one serial, two sets of facts: one call each
                return [self._authorize(r) for r in requests]
            entities[("RadarSite", site["id"])] = {"uid": site, "attrs": r["resource"], "parents": []}
            asked.append({"principal": uav, "action": ACTION, "resource": site, "context": r["context"]})
        answers = self._cedar(asked, list(entities.values()))
        return [self._authorize(r) if a.diagnostics.errors else a for r, a in zip(requests, answers)]

    def _rejected_on_error(self, result: Any, request: dict[str, Any]) -> PolicyResult | None:
        """Cedar skips a policy whose condition errors, so an erroring forbid would let the claim
        through: any evaluation error rejects with `policy-error` (fail closed)."""
        errors = [_one_line(e) for e in result.diagnostics.errors]
        if not errors:
            return None
        return PolicyResult("reject", [POLICY_ERROR, *self._reasons(result.diagnostics, "forbid")], errors, request)

    def decide(self, serial: str, principal: dict[str, Any], resource: dict[str, Any],
               context: dict[str, Any]) -> PolicyResult:
        """The complete decision over all the evidence gathered."""
        return self.decide_many([policy_input(serial, principal, resource, context)])[0]

    def decide_many(self, requests: Sequence[dict[str, Any]]) -> list[PolicyResult]:
        """`decide` for many requests (`policy_input` dicts), in one Cedar call where it can."""
        return [self._final(r, a) for r, a in zip(requests, self._authorize_many(requests))]

    def _final(self, request: dict[str, Any], result: Any) -> PolicyResult:
        failed = self._rejected_on_error(result, request)
        if failed is not None:
            return failed
        if result.allowed:
            return PolicyResult("accept", self._reasons(result.diagnostics, "permit"), [], request)
        return PolicyResult(self._denied(result.diagnostics),
                            self._reasons(result.diagnostics, "forbid") or ["default-deny"], [], request)

    def _denied(self, diag: Any) -> str:
        """A denial's decision: `inconclusive` where every forbid that fired says so, else reject."""
        fired = {r for r in diag.reasons if self.effects.get(r) == "forbid"}
        return INCONCLUSIVE if fired and fired <= self.inconclusive_forbids else "reject"

    def decide_without_evidence(self, serial: str, principal: dict[str, Any], resource: dict[str, Any],
                                context: dict[str, Any]) -> PolicyResult | None:
        """The decision with the radar not run (`context` says so), when it is final: a deny by a
        policy that reads no context (registry facts alone), or an evaluation error (the claim is
        rejected whatever the radar adds). Else None: the radar is needed."""
        return self.decide_many_without_evidence([policy_input(serial, principal, resource, context)])[0]

    def decide_many_without_evidence(self, requests: Sequence[dict[str, Any]]) -> list[PolicyResult | None]:
        """`decide_without_evidence` for many requests, in one Cedar call where it can."""
        return [self._early(r, a) for r, a in zip(requests, self._authorize_many(requests))]

    def _early(self, request: dict[str, Any], result: Any) -> PolicyResult | None:
        failed = self._rejected_on_error(result, request)
        if failed is not None:
            return failed
        final = self.context_free_forbids - self.inconclusive_forbids
        if result.allowed or not set(result.diagnostics.reasons) & final:
            return None
        return PolicyResult("reject", self._reasons(result.diagnostics, "forbid"), [], request)


def _names_site(node: Any) -> bool:
    """Whether a policy's JSON AST names a RadarSite entity (`RadarSite::"site"`)."""
    if isinstance(node, dict):
        if node.get("type") == "RadarSite" and "id" in node:
            return True
        return any(_names_site(v) for v in node.values())
    if isinstance(node, list):
        return any(_names_site(v) for v in node)
    return False


def _context_read(node: Any) -> set[str]:
    """The `context` attributes a policy's JSON AST (Cedar's JSON policy format) reads;
    `{"*"}` when it uses `context` as a whole (then nothing can be assumed)."""
    if isinstance(node, dict):
        for op in (".", "has"):
            inner = node.get(op)
            if isinstance(inner, dict) and inner.get("left") == {"Var": "context"}:
                return {str(inner.get("attr"))}
        if node.get("Var") == "context":
            return {"*"}
        return set().union(*(_context_read(v) for v in node.values()))
    if isinstance(node, list):
        return set().union(*(_context_read(v) for v in node))
    return set()
