"""Helpers shared by the tests: free ports for subprocess services, optional dependencies."""

import socket


def free_port() -> int:
    """A TCP port on 127.0.0.1 that nothing listens on (right now)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def require(module: str):
    """Import an optional test dependency: skipped on a developer machine without it, an error
    under CI (CI=true), where `make test` installs every extra and nothing may silently skip."""
    import importlib
    import os

    import pytest

    if os.environ.get("CI") == "true":
        return importlib.import_module(module)
    return pytest.importorskip(module)


def require_browser():
    """Chromium's path and Playwright's ``sync_playwright`` for a browser test module: skipped on
    a developer machine without them, an error under CI (``.ci/run`` installs Chromium)."""
    import os

    import pytest

    from web.screenshot import chromium_path

    in_ci = os.environ.get("CI") == "true"
    chromium = chromium_path()
    if chromium is None:
        if in_ci:
            raise RuntimeError("CI=true but Chromium is not installed: .ci/run must `apt-get install -y chromium`")
        pytest.skip("headless Chromium not installed (apt-get install chromium) — skipped", allow_module_level=True)
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        if in_ci:
            raise
        pytest.skip("playwright not installed (pip install playwright) — skipped", allow_module_level=True)
    return chromium, sync_playwright
