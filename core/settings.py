"""Every `AUTHN_*` environment variable the product reads: one `Variable` each (name, field,
meaning, default) and one immutable `Settings` holding their parsed values.

No other module reads an `AUTHN_*` variable (tests/test_settings.py). The environment is read
when `current()` is called, never at import: the test harness and `authn serve` set variables
after our modules are imported, and a value cannot go stale. A caller that needs several values
takes one snapshot. A malformed value is bad input naming its variable, whichever value the
caller wanted: the process fails closed instead of running on a half-read configuration.
Empty means unset. Paths whose default lives in a platform directory are None here; their
modules add that default (it needs `platformdirs`).

Both records are NamedTuples, not dataclasses, and the module has no `from __future__ import
annotations` (NamedTuple would compile each string annotation): a check imports it, in ~1 ms
this way against ~8 ms as frozen dataclasses (bytecode compiled, 2 cores).
"""

import os
from collections.abc import Mapping
from typing import Any, NamedTuple

from core.errors import BadInput

__all__ = ["VARIABLES", "Settings", "Variable", "current", "load", "name_of"]


class Variable(NamedTuple):
    """One environment variable: `kind` parses it (str, int or float; numbers must be
    positive), `choices` bounds a str, `default` says in words what unset means."""

    name: str
    field: str
    doc: str
    default: str
    kind: type = str
    choices: tuple[str, ...] = ()


VARIABLES: tuple[Variable, ...] = (
    Variable("AUTHN_DATABASE_URL", "database_url", "registry and audit database (SQLAlchemy URL); `--db` wins",
             "SQLite `registry.sqlite3` in the user data directory"),
    Variable("AUTHN_MODELS_DIR", "models_dir", "folder of user model bundles (`authn models`)",
             "`models` in the user data directory"),
    Variable("AUTHN_CACHE_DIR", "cache_dir", "cache of simulated training data sets",
             "`datasets` in the user cache directory"),
    Variable("AUTHN_FFT", "fft", "default FFT backend of radar processing (`signatures.dsp.fft`)", "numpy",
             choices=("numpy", "scipy")),
    Variable("AUTHN_LOG_KEY", "log_key", "the audit log's Ed25519 key file; `--log-key` wins",
             "`audit-log-key.pem` in the user data directory"),
    Variable("AUTHN_AUDIT_STH_LOG", "audit_sth_log", "JSON-lines file of periodic signed tree heads; `--sth-log` wins",
             "`audit-sth.jsonl` beside the log key"),
    Variable("AUTHN_AUDIT_WITNESS", "audit_witness", "witness of the log's heads: a folder or an http(s) URL; "
             "`--witness` wins", "no witness"),
    Variable("AUTHN_AUDIT_ORIGIN", "audit_origin", "origin line of a new log's checkpoints (fixed by its first "
             "append)", "`authn.invalid/audit/<random>`"),
    Variable("AUTHN_AUDIT_CHECKPOINT_EVERY", "audit_checkpoint_every", "a periodic head every this many entries",
             "64", kind=int),
    Variable("AUTHN_AUDIT_CHECKPOINT_SECONDS", "audit_checkpoint_seconds", "... or after this many seconds",
             "300", kind=float),
    Variable("AUTHN_AUDIT_APPEND_CHECK", "audit_append_check", "how far back each append proves the log: "
             "`window` (from the last periodic head) or `full` (O(n))", "window", choices=("window", "full")),
    # written by `authn serve` from its options for its worker processes (`authn.service.settings`)
    Variable("AUTHN_SERVE_DB_URL", "serve_db_url", "the service's database (`--db`)", "as AUTHN_DATABASE_URL"),
    Variable("AUTHN_SERVE_POLICY", "serve_policy", "the service's Cedar policy (`--policy`)", "the shipped policy"),
    Variable("AUTHN_SERVE_MAX_UPLOAD_BYTES", "serve_max_upload_bytes", "largest upload (`--max-upload-mib`)",
             "64 MiB", kind=int),
    Variable("AUTHN_SERVE_MAX_BATCH_FILES", "serve_max_batch_files", "most files in one batch request", "64",
             kind=int),
    Variable("AUTHN_SERVE_MAX_DRONES", "serve_max_drones", "most drones one rid_capture may name (`--max-drones`)",
             "64", kind=int),
    Variable("AUTHN_SERVE_UPLOAD_TIMEOUT_S", "serve_upload_timeout_s", "seconds an upload may take "
             "(`--upload-timeout-s`)", "60", kind=float),
    Variable("AUTHN_SERVE_MAX_BODY_BYTES", "serve_max_body_bytes", "largest body that is not an upload "
             "(`--max-body-kib`)", "64 KiB", kind=int),
    Variable("AUTHN_SERVE_BODY_TIMEOUT_S", "serve_body_timeout_s", "seconds such a body may take "
             "(`--body-timeout-s`)", "10", kind=float),
    Variable("AUTHN_SERVE_TRUSTED_PROXY_HEADER", "serve_trusted_proxy_header", "header naming the client behind a "
             "trusted proxy (`--trusted-proxy-header`)", "the peer is the client"),
    Variable("AUTHN_SERVE_TRUSTED_PROXIES", "serve_trusted_proxies", "proxies whose header is believed "
             "(`--trusted-proxies`)", "none"),
    Variable("AUTHN_SERVE_FIGURES_DIR", "serve_figures_dir", "where `figure=true` checks keep figures "
             "(`--figures-dir`)", "`figures` in the user data directory"),
)


class Settings(NamedTuple):
    """The parsed value of every variable in `VARIABLES` (same order, one field each)."""

    database_url: str | None = None
    models_dir: str | None = None
    cache_dir: str | None = None
    fft: str = "numpy"
    log_key: str | None = None
    audit_sth_log: str | None = None
    audit_witness: str | None = None
    audit_origin: str | None = None
    audit_checkpoint_every: int = 64
    audit_checkpoint_seconds: float = 300.0
    audit_append_check: str = "window"
    serve_db_url: str | None = None
    serve_policy: str | None = None
    serve_max_upload_bytes: int = 64 * 2**20
    serve_max_batch_files: int = 64
    serve_max_drones: int = 64
    serve_upload_timeout_s: float = 60.0
    serve_max_body_bytes: int = 64 * 2**10
    serve_body_timeout_s: float = 10.0
    serve_trusted_proxy_header: str | None = None
    serve_trusted_proxies: str = ""
    serve_figures_dir: str | None = None


def _parse(var: Variable, raw: str) -> str | int | float:
    if var.kind is str:
        if var.choices and raw not in var.choices:
            raise BadInput(f"${var.name}: {' or '.join(repr(c) for c in var.choices)}, got {raw!r}")
        return raw
    try:
        value = var.kind(raw)
    except ValueError:
        raise BadInput(f"${var.name}: not a number: {raw!r}") from None
    if not value > 0:
        raise BadInput(f"${var.name}: must be positive, got {raw!r}")
    return value


def load(environ: Mapping[str, str]) -> Settings:
    """The settings that `environ` sets (unset or empty: the default)."""
    values: dict[str, Any] = {v.field: _parse(v, raw) for v in VARIABLES if (raw := environ.get(v.name))}
    return Settings(**values)


def current() -> Settings:
    """The settings of this process's environment as it is now."""
    return load(os.environ)


def name_of(field: str) -> str:
    """The variable behind a `Settings` field (`authn serve` writes its workers' environment)."""
    return _NAMES[field]


_NAMES = {v.field: v.name for v in VARIABLES}
