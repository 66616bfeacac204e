"""What one server needs to know, passed explicitly (and through the environment to the
worker processes uvicorn spawns, which import `authn.service.app:app_from_env`)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from core.settings import Settings as _Environment
from core.settings import current, name_of

if TYPE_CHECKING:
    from authn.service.clients import ClientAddress

#: the defaults are the environment's (`core.settings`), written once there
_DEFAULT = _Environment._field_defaults


@dataclass(frozen=True)
class Settings:
    db_url: str | None = None
    policy_path: str | None = None
    max_upload_bytes: int = _DEFAULT["serve_max_upload_bytes"]
    #: most files in one POST /v1/checks:batch
    max_batch_files: int = _DEFAULT["serve_max_batch_files"]
    #: most drones one `rid_capture` may name in a dwell's window (one decision each; 413 beyond)
    max_drones: int = _DEFAULT["serve_max_drones"]
    #: seconds an upload's body may take to arrive (408 after)
    upload_timeout_s: float = _DEFAULT["serve_upload_timeout_s"]
    #: largest body of a request that is not an upload (JSON; 413 beyond)
    max_body_bytes: int = _DEFAULT["serve_max_body_bytes"]
    #: seconds such a body may take to arrive (408 after)
    body_timeout_s: float = _DEFAULT["serve_body_timeout_s"]
    #: header naming the client when the peer is a trusted proxy (e.g. X-Forwarded-For); None: the peer
    trusted_proxy_header: str | None = None
    #: the proxies (CIDR,...) whose trusted_proxy_header is believed
    trusted_proxies: str = _DEFAULT["serve_trusted_proxies"]
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
        """The settings as environment variables for worker processes (`core.settings` names them)."""
        values = {env: getattr(self, field) for field, env in _ENV_FIELDS}
        return {name_of(env): str(value) for env, value in values.items() if value is not None}

    @classmethod
    def from_env(cls) -> "Settings":
        """What `to_env` wrote (a worker process's settings), from `core.settings`."""
        env = current()
        values = {field: getattr(env, name) for field, name in _ENV_FIELDS}
        return cls(**{**values, "db_url": env.serve_db_url or env.database_url})


#: Each field and the `core.settings` field that carries it to worker processes.
_ENV_FIELDS = (("db_url", "serve_db_url"), ("policy_path", "serve_policy"),
               ("max_upload_bytes", "serve_max_upload_bytes"), ("max_batch_files", "serve_max_batch_files"),
               ("max_drones", "serve_max_drones"), ("upload_timeout_s", "serve_upload_timeout_s"),
               ("max_body_bytes", "serve_max_body_bytes"), ("body_timeout_s", "serve_body_timeout_s"),
               ("trusted_proxy_header", "serve_trusted_proxy_header"),
               ("trusted_proxies", "serve_trusted_proxies"), ("figures_dir", "serve_figures_dir"))
