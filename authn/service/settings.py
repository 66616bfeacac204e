"""What one server needs to know, passed explicitly (and through the environment to the
worker processes uvicorn spawns, which import `authn.service.app:app_from_env`)."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

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
    #: where `figure=true` checks keep their evidence figures (`<audit id>.png`); None: the
    #: user data directory's `figures`
    figures_dir: str | None = None

    def figures_folder(self) -> Path:
        from platformdirs import user_data_dir

        return Path(self.figures_dir or Path(user_data_dir("authn")) / "figures").expanduser()

    def to_env(self) -> dict[str, str]:
        """The settings as environment variables for worker processes."""
        env = {f"{ENV_PREFIX}MAX_UPLOAD_BYTES": str(self.max_upload_bytes),
               f"{ENV_PREFIX}MAX_BATCH_FILES": str(self.max_batch_files),
               f"{ENV_PREFIX}MAX_DRONES": str(self.max_drones),
               f"{ENV_PREFIX}UPLOAD_TIMEOUT_S": str(self.upload_timeout_s)}
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
                   figures_dir=env.get(f"{ENV_PREFIX}FIGURES_DIR"))
