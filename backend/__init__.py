"""nmkane REST service: runs simulations on request and keeps them (SQLite).

``create_app(settings)`` builds the FastAPI app; ``serve()`` runs it (with the 3D web app).
"""

from .app import create_app
from .config import Settings

__all__ = ["create_app", "Settings"]
