"""Who is calling and may they: the API key (Bearer token or X-API-Key) names a role, and
the service's Cedar policy (authn/policies/service.cedar) decides per action."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import cedarpy

ACTIONS = ("check", "read_audit", "checkpoint", "read_registry", "write_registry")


class Unauthenticated(Exception):
    """No key, or one that is unknown or revoked (401)."""


class Forbidden(Exception):
    """A valid key whose role may not do this (403)."""


@dataclass(frozen=True)
class Caller:
    key_id: int
    role: str


def _text(name: str) -> str:
    from authn.policy import SHIPPED_POLICIES

    return (SHIPPED_POLICIES / name).read_text(encoding="utf-8")


class RolePolicy:
    """The service's Cedar policy, parsed and validated once per worker."""

    def __init__(self) -> None:
        text, schema = _text("service.cedar"), _text("service.cedarschema")
        result = cedarpy.validate_policies(text, schema)
        if not result.validation_passed:
            raise RuntimeError(f"service.cedar does not validate: {result.errors[0] if result.errors else '?'}")
        self.policy_set = cedarpy.PolicySet.from_str(text)
        self.schema = cedarpy.Schema.from_str(schema)

    def allows(self, caller: Caller, action: str) -> bool:
        request: dict[str, Any] = {"principal": {"type": "ApiKey", "id": str(caller.key_id)},
                                   "action": {"type": "Action", "id": action},
                                   "resource": {"type": "Service", "id": "authn"}, "context": {}}
        entities = [{"uid": {"type": "ApiKey", "id": str(caller.key_id)}, "attrs": {"role": caller.role},
                     "parents": []},
                    {"uid": {"type": "Service", "id": "authn"}, "attrs": {}, "parents": []}]
        return bool(cedarpy.is_authorized(request, self.policy_set, entities, schema=self.schema).allowed)


def token_of(headers: Any) -> str | None:
    """The presented token: `Authorization: Bearer T` or `X-API-Key: T`."""
    auth = headers.get("authorization")
    if auth:
        scheme, _, value = auth.partition(" ")
        if scheme.lower() == "bearer" and value.strip():
            return value.strip()
        return None
    key = headers.get("x-api-key")
    return key.strip() if key and key.strip() else None
