"""nmkane REST service: runs simulations on request and keeps them (SQLite).

``create_app(settings)`` builds the FastAPI app; ``serve()`` runs it beside the apps other
packages contribute (the 3D web app).  Names load on first use, so that the ``nmkane``
command can list ``serve`` without importing FastAPI.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

__all__ = ["create_app", "Settings"]

if TYPE_CHECKING:
    from .app import create_app
    from .config import Settings


def __getattr__(name: str) -> Any:
    if name == "create_app":
        from .app import create_app

        return create_app
    if name == "Settings":
        from .config import Settings

        return Settings
    raise AttributeError(name)
