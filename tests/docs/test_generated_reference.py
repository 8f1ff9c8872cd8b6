"""The command-line and REST pages read whole in the repository: their generated tables are
committed in ``docs/cli.md`` and ``docs/rest.md`` and must be what the generators make from
the code now, and the REST page names every route the app serves (those outside the OpenAPI
document included), so a new route or option without its docs fails here."""

from __future__ import annotations

import difflib
import sys
from pathlib import Path

import pytest
from fastapi import FastAPI
from starlette.routing import Mount

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "scripts" / "docs"))
try:
    import gen_cli
    import gen_rest
finally:
    sys.path.pop(0)

GENERATORS = {"cli.md": gen_cli, "rest.md": gen_rest}


def _stale(page: str, committed: str, generated: str) -> str:
    diff = "".join(
        list(difflib.unified_diff(committed.splitlines(True), generated.splitlines(True), f"docs/{page}", "generated"))[
            :60
        ]
    )
    script = f"scripts/docs/{GENERATORS[page].__name__}.py"
    return f"docs/{page} is stale: refresh it with `python {script} --write` and commit it\n{diff}"


@pytest.mark.parametrize("page", sorted(GENERATORS))
def test_the_committed_reference_page_is_what_its_generator_makes_now(page):
    committed = (ROOT / "docs" / page).read_text()
    generated = GENERATORS[page].render(committed)
    assert committed == generated, _stale(page, committed, generated)


def test_a_stale_generated_block_is_refreshed_and_hand_written_text_kept():
    committed = (ROOT / "docs" / "rest.md").read_text()
    stale = committed.replace("| [`GET /api/runs`]", "| [`GET /api/old-runs`]", 1)
    stale = stale.replace("## Behaviour", "## Behaviour (hand-written)", 1)
    assert stale != committed
    parts = gen_rest.parts()
    refreshed = gen_rest.splice(stale, parts, "scripts/docs/gen_rest.py")
    assert "/api/old-runs" not in refreshed and "## Behaviour (hand-written)" in refreshed
    assert refreshed == committed.replace("## Behaviour", "## Behaviour (hand-written)", 1)


def test_a_block_without_its_end_marker_is_an_error():
    text = "<!-- begin nmkane:rest-summary -->\nold\n"
    with pytest.raises(RuntimeError, match="rest-summary"):
        gen_rest.splice(text, {"rest-summary": "new"}, "scripts/docs/gen_rest.py")


def served_routes(app: FastAPI) -> set[str]:
    """Every ``METHOD /path`` the app answers (HEAD left out: every GET answers it) and
    every mounted ``/path/``: the app's own routes (its docs) and those of its routers."""
    from backend.routes import ROUTERS

    out: set[str] = set()
    for route in [*app.routes, *(r for router in ROUTERS for r in router.routes)]:
        if isinstance(route, Mount):
            out.add(route.path + "/")
        for method in getattr(route, "methods", None) or ():
            if method != "HEAD":
                out.add(f"{method} {route.path}")
    return out


def unnamed_routes(app: FastAPI, text: str) -> list[str]:
    """The routes of ``served_routes`` that ``text`` does not name in code (`` `GET /path` ``)."""
    return sorted(r for r in served_routes(app) if f"`{r}`" not in text)


def _app(data_dir: Path) -> FastAPI:
    from backend.app import create_app
    from backend.config import Settings

    return create_app(Settings(data_dir=data_dir, warm_kernels=False))


def test_every_route_the_app_serves_is_named_on_the_rest_page(tmp_path):
    app = _app(tmp_path)
    documented = {f"{m.upper()} {p}" for p, item in app.openapi()["paths"].items() for m in item}
    assert documented <= served_routes(app), "the route walk misses routes of the OpenAPI document"
    text = (ROOT / "docs" / "rest.md").read_text()
    missing = unnamed_routes(app, text)
    assert not missing, (
        f"docs/rest.md does not name {missing}: refresh it (`python scripts/docs/gen_rest.py --write`); "
        "a route outside the OpenAPI document needs a sentence in the hand-written part"
    )


def test_a_new_route_without_docs_is_caught(tmp_path):
    app = _app(tmp_path)
    app.get("/api/undocumented", include_in_schema=False)(lambda: None)
    text = (ROOT / "docs" / "rest.md").read_text()
    assert unnamed_routes(app, text) == ["GET /api/undocumented"]
