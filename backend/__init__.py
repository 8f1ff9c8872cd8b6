"""nmkane REST service: runs simulations on request and keeps them (SQLite)."""

from .app import create_app
from .config import Settings

__all__ = ["create_app", "Settings"]
