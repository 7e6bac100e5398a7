"""The interactive docs work offline: ``/docs`` names no outside address, and every script, style sheet and icon it
names is served by the service itself."""

from __future__ import annotations

import re

from fastapi.testclient import TestClient


def test_the_docs_page_and_its_assets_come_from_the_service(api: TestClient) -> None:
    page = api.get("/docs")
    assert page.status_code == 200 and page.headers["content-type"].startswith("text/html")
    refs = re.findall(r"""(?:src|href)=['"]([^'"]+)['"]""", page.text) + re.findall(r"url: '([^']+)'", page.text)
    assert refs, page.text
    outside = [r for r in refs if re.match(r"^(https?:)?//", r)]
    assert outside == [], outside
    for ref in refs:
        r = api.get(ref)
        assert r.status_code == 200 and len(r.content) > 100, (ref, r.status_code)
    assert api.get("/docs/assets/swagger-ui-bundle.js").headers["content-type"].split(";")[0] in (
        "text/javascript", "application/javascript",
    )  # fmt: skip
    assert api.get("/docs/oauth2-redirect").status_code == 200
