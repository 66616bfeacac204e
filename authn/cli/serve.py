"""`authn serve`: the decision engine as an HTTP service (docs/service.md)."""

from __future__ import annotations

from pathlib import Path

import typer


def serve(
    ctx: typer.Context,
    host: str = typer.Option("127.0.0.1", "--host", help="Address to listen on."),
    port: int = typer.Option(8080, "--port", min=1, max=65535, help="TCP port."),
    workers: int = typer.Option(1, "--workers", min=1, max=64, help="Worker processes (one Checker each)."),
    max_upload_mib: float = typer.Option(64.0, "--max-upload-mib", min=0.001, max=1024.0,
                                         help="Largest upload accepted (413 beyond it)."),
    policy: Path | None = typer.Option(None, "--policy", help="Cedar decision policy replacing the default."),
    upload_timeout_s: float = typer.Option(60.0, "--upload-timeout-s", min=0.1, max=3600.0,
                                           help="Seconds an upload may take to arrive (408 after)."),
    timeout_keep_alive: int = typer.Option(5, "--keep-alive-s", min=1, max=300, help="Idle keep-alive timeout."),
) -> None:
    """Serve checks, the audit log and the registry over HTTP (OpenAPI at /docs).

    Clients authenticate with API keys: `authn keys api create --role operator`.

    Example: authn serve --port 8080 --workers 2
    """
    import os

    from authn.service.settings import Settings

    settings = Settings(db_url=ctx.obj.db_url, policy_path=str(policy) if policy else None,
                        max_upload_bytes=int(max_upload_mib * 2**20), upload_timeout_s=upload_timeout_s)
    os.environ.update(settings.to_env())  # read by each worker process's app factory
    from registry.db import get_engine

    get_engine(settings.db_url)  # migrate once here, before the workers race to
    config = dict(app="authn.service.app:app_from_env", factory=True, timeout_keep_alive=timeout_keep_alive,
                  limit_concurrency=256, log_level="info", server_header=False)
    from authn.service.workers import run_workers

    typer.echo(f"authn serve: {workers} worker(s) on http://{host}:{port} (OpenAPI at /docs)", err=True)
    raise typer.Exit(run_workers(host, port, workers, config))
