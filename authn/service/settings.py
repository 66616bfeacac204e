"""What one server needs to know, passed explicitly (and through the environment to the
worker processes uvicorn spawns, which import `authn.service.app:app_from_env`)."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from authn.service.clients import ClientAddress

ENV_PREFIX = "AUTHN_SERVE_"


@dataclass(frozen=True)
class Settings:
    db_url: str | None = None
    policy_path: str | None = None
    max_upload_bytes: int = 64 * 2**20
    #: most files in one POST /v1/checks:batch
    max_batch_files: int = 64
    #: most drones one `rid_capture` may name in a dwell's window (one decision each; 413 beyond)
    max_drones: int = 64
    #: seconds an upload's body may take to arrive (408 after)
    upload_timeout_s: float = 60.0
    #: largest body of a request that is not an upload (JSON; 413 beyond)
    max_body_bytes: int = 64 * 2**10
    #: seconds such a body may take to arrive (408 after)
    body_timeout_s: float = 10.0
    #: header naming the client when the peer is a trusted proxy (e.g. X-Forwarded-For); None: the peer
    trusted_proxy_header: str | None = None
    #: the proxies (CIDR,...) whose trusted_proxy_header is believed
    trusted_proxies: str = ""
    #: where `figure=true` checks keep their evidence figures (`<audit id>.png`); None: the
    #: user data directory's `figures`
    figures_dir: str | None = None

    def figures_folder(self) -> Path:
        from platformdirs import user_data_dir

        return Path(self.figures_dir or Path(user_data_dir("authn")) / "figures").expanduser()

    def clients(self) -> "ClientAddress":
        """How a request's client address is found (through the trusted proxies only)."""
        from authn.service.clients import ClientAddress, parse_networks

        header = self.trusted_proxy_header.strip().lower() if self.trusted_proxy_header else None
        return ClientAddress(header, parse_networks(self.trusted_proxies))

    def to_env(self) -> dict[str, str]:
        """The settings as environment variables for worker processes."""
        env = {f"{ENV_PREFIX}MAX_UPLOAD_BYTES": str(self.max_upload_bytes),
               f"{ENV_PREFIX}MAX_BATCH_FILES": str(self.max_batch_files),
               f"{ENV_PREFIX}MAX_DRONES": str(self.max_drones),
               f"{ENV_PREFIX}UPLOAD_TIMEOUT_S": str(self.upload_timeout_s),
               f"{ENV_PREFIX}MAX_BODY_BYTES": str(self.max_body_bytes),
               f"{ENV_PREFIX}BODY_TIMEOUT_S": str(self.body_timeout_s),
               f"{ENV_PREFIX}TRUSTED_PROXIES": self.trusted_proxies}
        if self.trusted_proxy_header:
            env[f"{ENV_PREFIX}TRUSTED_PROXY_HEADER"] = self.trusted_proxy_header
        if self.db_url:
            env[f"{ENV_PREFIX}DB_URL"] = self.db_url
        if self.policy_path:
            env[f"{ENV_PREFIX}POLICY"] = self.policy_path
        if self.figures_dir:
            env[f"{ENV_PREFIX}FIGURES_DIR"] = self.figures_dir
        return env

    @classmethod
    def from_env(cls) -> "Settings":
        env = os.environ
        return cls(db_url=env.get(f"{ENV_PREFIX}DB_URL") or env.get("AUTHN_DATABASE_URL"),
                   policy_path=env.get(f"{ENV_PREFIX}POLICY"),
                   max_upload_bytes=int(env.get(f"{ENV_PREFIX}MAX_UPLOAD_BYTES", 64 * 2**20)),
                   max_batch_files=int(env.get(f"{ENV_PREFIX}MAX_BATCH_FILES", 64)),
                   max_drones=int(env.get(f"{ENV_PREFIX}MAX_DRONES", 64)),
                   upload_timeout_s=float(env.get(f"{ENV_PREFIX}UPLOAD_TIMEOUT_S", 60.0)),
                   max_body_bytes=int(env.get(f"{ENV_PREFIX}MAX_BODY_BYTES", 64 * 2**10)),
                   body_timeout_s=float(env.get(f"{ENV_PREFIX}BODY_TIMEOUT_S", 10.0)),
                   trusted_proxy_header=env.get(f"{ENV_PREFIX}TRUSTED_PROXY_HEADER") or None,
                   trusted_proxies=env.get(f"{ENV_PREFIX}TRUSTED_PROXIES", ""),
                   figures_dir=env.get(f"{ENV_PREFIX}FIGURES_DIR"))
