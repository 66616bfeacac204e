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
    header_timeout_s: float = typer.Option(5.0, "--header-timeout-s", min=0.1, max=300.0,
                                           help="Seconds a connection may take to send a request head "
                                                "(closed after)."),
    max_connections: int = typer.Option(1024, "--max-connections", min=1, max=1_000_000,
                                        help="Open connections per worker (the oldest idle one makes room)."),
    max_connections_per_client: int = typer.Option(64, "--max-connections-per-client", min=1, max=1_000_000,
                                                   help="Per client address and worker: open connections (its "
                                                        "oldest idle one makes room) and requests in progress "
                                                        "(503 beyond)."),
    max_in_flight: int = typer.Option(256, "--max-in-flight", min=1, max=100_000,
                                      help="Requests in progress per worker (503 beyond; an address holding m "
                                           "gets another only while more than m are free)."),
    max_body_kib: float = typer.Option(64.0, "--max-body-kib", min=1.0, max=65536.0,
                                       help="Largest body of a request that is not an upload (413 beyond it)."),
    body_timeout_s: float = typer.Option(10.0, "--body-timeout-s", min=0.1, max=3600.0,
                                         help="Seconds such a body may take to arrive (408 after)."),
    max_bodies_per_client: int = typer.Option(16, "--max-bodies-per-client", min=1, max=100_000,
                                              help="Per client address and worker: requests receiving a body "
                                                   "at once (503 beyond)."),
    trusted_proxy_header: str | None = typer.Option(None, "--trusted-proxy-header",
                                                    help="Header naming the client (e.g. X-Forwarded-For), "
                                                         "believed only from --trusted-proxies."),
    trusted_proxies: str = typer.Option("", "--trusted-proxies",
                                        help="Comma-separated addresses or CIDR networks of your proxies."),
    max_drones: int = typer.Option(64, "--max-drones", min=1, max=1_000_000,
                                   help="Most drones one rid_capture may name in a dwell's window (one "
                                        "decision each; 413 beyond, refused before any is decided)."),
    figures_dir: Path | None = typer.Option(None, "--figures-dir",
                                            help="Where figure=true checks keep their evidence figures "
                                                 "(default: figures in the user data directory)."),
) -> None:
    """Serve checks, the audit log and the registry over HTTP (OpenAPI at /docs).

    Clients authenticate with API keys: `authn keys api create --role operator`.

    Example: authn serve --port 8080 --workers 2
    """
    import os

    from authn.service.connections import ConnectionLimits
    from authn.service.settings import Settings

    if max_connections_per_client > max_connections:
        raise typer.BadParameter("may not exceed --max-connections", param_hint="--max-connections-per-client")
    _check_proxies(trusted_proxy_header, trusted_proxies)
    limits = ConnectionLimits(header_timeout_s=header_timeout_s, max_connections=max_connections,
                              max_connections_per_client=max_connections_per_client, max_in_flight=max_in_flight,
                              max_bodies_per_client=max_bodies_per_client)

    settings = Settings(db_url=ctx.obj.db_url, policy_path=str(policy) if policy else None,
                        max_upload_bytes=int(max_upload_mib * 2**20), upload_timeout_s=upload_timeout_s,
                        max_drones=max_drones,
                        max_body_bytes=int(max_body_kib * 2**10), body_timeout_s=body_timeout_s,
                        trusted_proxy_header=trusted_proxy_header, trusted_proxies=trusted_proxies,
                        figures_dir=str(figures_dir) if figures_dir else None)
    os.environ.update(settings.to_env())  # read by each worker process's app factory
    from registry.db import get_engine

    get_engine(settings.db_url)  # migrate once here, before the workers race to
    config = dict(app="authn.service.app:app_from_env", factory=True, timeout_keep_alive=timeout_keep_alive,
                  log_level="info", server_header=False,  # connection and request limits: `limits`
                  proxy_headers=False)  # uvicorn would believe X-Forwarded-For from 127.0.0.1: clients.py decides
    from authn.service.workers import run_workers

    typer.echo(f"authn serve: {workers} worker(s) on http://{host}:{port} (OpenAPI at /docs)", err=True)
    raise typer.Exit(run_workers(host, port, workers, config, limits))


def _check_proxies(header: str | None, proxies: str) -> None:
    """Both proxy options or neither; every entry an address or CIDR network; a header name."""
    import re

    from authn.service.clients import parse_networks

    if bool(header) != bool(proxies.strip()):
        raise typer.BadParameter("--trusted-proxy-header and --trusted-proxies go together",
                                 param_hint="--trusted-proxies")
    if header and not re.fullmatch(r"[A-Za-z0-9-]{1,64}", header):
        raise typer.BadParameter("a header name (letters, digits, '-')", param_hint="--trusted-proxy-header")
    try:
        parse_networks(proxies)
    except ValueError as exc:
        raise typer.BadParameter(str(exc), param_hint="--trusted-proxies") from None
