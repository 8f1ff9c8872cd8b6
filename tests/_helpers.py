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
