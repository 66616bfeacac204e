"""`POST /v1/checks` with `figure=true` draws the decision's evidence figure once the decision
is recorded; `GET /v1/checks/{audit_id}/figure.png` serves it (404 for a check without one)."""

from __future__ import annotations

import pytest

pytest.importorskip("matplotlib", reason="the plot extra (matplotlib) is not installed")

from tests.service.server import M600


def test_a_checks_figure_is_served(server, keys, returns) -> None:
    from authn import figure

    with server.client(keys.operator) as c:
        plain = c.post("/v1/checks", files={"file": ("type.h5", returns["type"].read_bytes())},
                       data={"serial": M600})
        drawn = c.post("/v1/checks", files={"file": ("type.h5", returns["type"].read_bytes())},
                       data={"serial": M600, "figure": "true"})
        assert plain.status_code == drawn.status_code == 200
        png = c.get(f"/v1/checks/{drawn.json()['audit_id']}/figure.png")
        missing = c.get(f"/v1/checks/{plain.json()['audit_id']}/figure.png")
    assert png.status_code == 200 and png.headers["content-type"] == "image/png"
    assert png.content[:8] == b"\x89PNG\r\n\x1a\n"
    width, height = int.from_bytes(png.content[16:20], "big"), int.from_bytes(png.content[20:24], "big")
    assert (width, height) == (round(figure.SIZE_IN[0] * figure.DPI), round(figure.SIZE_IN[1] * figure.DPI))
    assert missing.status_code == 404 and "figure=true" in missing.json()["error"]
    with server.client() as anonymous:
        assert anonymous.get(f"/v1/checks/{drawn.json()['audit_id']}/figure.png").status_code == 401
