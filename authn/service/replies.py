"""The one-line JSON error a pure ASGI layer answers with, before or instead of the app."""

from __future__ import annotations

import json
from collections.abc import Sequence
from typing import Any


async def reply(send: Any, status: int, message: str, headers: Sequence[tuple[bytes, bytes]] = ()) -> None:
    """`{"error": message}` with `connection: close`: a body the app never read is not
    parsed as the next request."""
    body = json.dumps({"error": message}).encode()
    await send({"type": "http.response.start", "status": status,
                "headers": [(b"content-type", b"application/json"), (b"content-length", str(len(body)).encode()),
                            (b"connection", b"close"), *headers]})
    await send({"type": "http.response.body", "body": body})
