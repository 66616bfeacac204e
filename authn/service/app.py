"""The application factory: routes under /v1, health at /healthz and /readyz, Prometheus
at /metrics, OpenAPI at /docs. Every error answers `{"error": "<one line>"}`."""

from __future__ import annotations

import logging
import os
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from typing import Any

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse, Response
from starlette.exceptions import HTTPException

from core.errors import AuthnException, BadInput, OverLimit, describe, one_line
from authn.service.auth import Unauthenticated
from authn.service.runtime import Runtime
from authn.service.settings import Settings

log = logging.getLogger("authn.service")


def _error(request: Request, status: int, message: str, kind: str, headers: dict[str, str] | None = None
           ) -> JSONResponse:
    rt: Runtime | None = getattr(request.app.state, "runtime", None)
    if rt is not None:
        rt.metrics.error(status, kind)
    return JSONResponse({"error": one_line(message)}, status_code=status, headers=headers)


def _validation_message(exc: RequestValidationError) -> str:
    errors = exc.errors()
    if not errors:
        return "invalid request"
    first = errors[0]
    loc = ".".join(str(p) for p in first.get("loc", ()) if p not in ("body", "query", "path"))
    return f"{loc}: {first.get('msg', 'invalid')}" if loc else str(first.get("msg", "invalid"))


def _install_error_handlers(app: FastAPI) -> None:
    @app.exception_handler(Unauthenticated)  # a route the gate did not authenticate: fail closed
    async def _unauthenticated(request: Request, exc: Unauthenticated) -> JSONResponse:
        return _error(request, 401, str(exc), "unauthenticated", {"WWW-Authenticate": "Bearer"})

    @app.exception_handler(HTTPException)
    async def _http(request: Request, exc: HTTPException) -> JSONResponse:
        return _error(request, exc.status_code, str(exc.detail), "http", getattr(exc, "headers", None))

    @app.exception_handler(RequestValidationError)
    async def _invalid(request: Request, exc: RequestValidationError) -> JSONResponse:
        return _error(request, 422, _validation_message(exc), "validation")

    @app.exception_handler(AuthnException)
    async def _ours(request: Request, exc: AuthnException) -> JSONResponse:
        if isinstance(exc, BadInput):  # past a configured cap (OverLimit): too large, 413
            return _error(request, 413 if isinstance(exc, OverLimit) else 400, describe(exc), "bad-input")
        log.warning("system fault on %s %s: %s", request.method, request.url.path, describe(exc))
        return _error(request, 503, describe(exc), "system")

    @app.exception_handler(Exception)
    async def _unexpected(request: Request, exc: Exception) -> JSONResponse:
        log.error("internal error on %s %s: %s", request.method, request.url.path, describe(exc))
        return _error(request, 500, describe(exc), "internal")


def create_app(settings: Settings) -> FastAPI:
    """One application with its own runtime (loaded in the lifespan, once per worker)."""
    from authn.service import checks, records

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        app.state.runtime = Runtime.load(settings)
        try:
            yield
        finally:
            app.state.runtime.close()

    app = FastAPI(title="authn", version="1", lifespan=lifespan,
                  description="Radar micro-Doppler + Remote ID identity authentication of UAVs, as a service. "
                              "Authenticate with `Authorization: Bearer <key>` (`authn keys api create`).")
    _install_error_handlers(app)
    app.include_router(checks.router)
    app.include_router(records.router)

    @app.get("/healthz", tags=["health"])
    async def healthz() -> dict[str, Any]:
        """The process is up (`worker`: its process id, to see how connections spread)."""
        return {"status": "ok", "worker": os.getpid()}

    @app.get("/readyz", tags=["health"], responses={503: {"description": "not ready, or saturated"}})
    async def readyz(request: Request) -> Any:
        """Database reachable, its schema at the current migration, classifiers loaded, and this
        worker not saturated (`load`: its connections and requests in flight against the limits;
        `saturated`: new requests would get 503, or every connection slot holds a request). 503
        unless ready."""
        from authn.service.connections import current
        from registry.migrations import VERSION_QUERY, is_current

        rt: Runtime = request.app.state.runtime
        guard = current()
        load = {"worker": os.getpid(), **(guard.snapshot() if guard is not None else {})}
        saturated = guard is not None and guard.saturated()
        try:
            current_schema = is_current(await rt.run(lambda: rt.checker.db.fetch(VERSION_QUERY)))
        except Exception as exc:  # noqa: BLE001 - any database failure means not ready
            return JSONResponse({"ready": False, "error": one_line(describe(exc)), "saturated": saturated,
                                 "load": load}, status_code=503)
        doc = {"ready": current_schema and bool(rt.models) and not saturated, "database": "ok",
               "migrations_current": current_schema, "models": rt.models, "saturated": saturated, "load": load}
        return JSONResponse(doc, status_code=200 if doc["ready"] else 503)

    @app.get("/metrics", tags=["health"], response_class=Response)
    async def metrics(request: Request) -> Response:
        """Prometheus text format (this worker's counters)."""
        return Response(request.app.state.runtime.metrics.render(), media_type="text/plain; version=0.0.4")

    _add_layers(app, settings)
    return app


def api_routes(app: FastAPI) -> list[Any]:
    """Every API route of the app, those of included routers too (their paths carry the prefix)."""
    found: list[Any] = []
    for route in app.routes:
        inner = getattr(route, "original_router", None)
        if inner is not None and route.include_context.prefix:
            raise RuntimeError("include routers with the prefix on the APIRouter, not in include_router")
        found.extend(inner.routes if inner is not None else [route] if hasattr(route, "dependant") else [])
    return found


def _add_layers(app: FastAPI, settings: Settings) -> None:
    """The pure ASGI layers, outermost last: request slots, then the key (before any body is
    read), then the body's limit and timeout."""
    from authn.service.gate import Authenticate, route_actions
    from authn.service.limits import FORM_OVERHEAD, BodyLimits, BodyRule, RequestLimit, body_rules

    routes, clients = api_routes(app), settings.clients()
    upload = BodyRule(settings.max_upload_bytes + FORM_OVERHEAD, settings.upload_timeout_s, "upload",
                      settings.max_upload_bytes, multipart=True)
    other = BodyRule(settings.max_body_bytes, settings.body_timeout_s, "body", settings.max_body_bytes)
    app.add_middleware(BodyLimits, rules=body_rules(routes, upload, other), other=other, clients=clients)
    app.add_middleware(Authenticate, actions=route_actions(routes))
    app.add_middleware(RequestLimit, clients=clients)  # outermost: a slow upload counts as in flight


def app_from_env() -> FastAPI:
    """uvicorn's factory in each worker process (`authn serve` puts the settings in the environment)."""
    return create_app(Settings.from_env())
