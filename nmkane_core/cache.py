"""Where nmkane keeps what it computes once: the on-disk cache folders.

``$NMKANE_CACHE_DIR`` (or ``$XDG_CACHE_HOME/nmkane``, or ``~/.cache/nmkane``) is the root;
compiled kernels live under ``kernels/``; other faces (the web app's rendered matrices)
keep their own sub-folders next to it, keyed by :meth:`nmkane_core.System.kernel_key`.
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["cache_root", "kernel_dir"]


def cache_root() -> Path:
    """The root of nmkane's cache: $NMKANE_CACHE_DIR, else $XDG_CACHE_HOME/nmkane, else ~/.cache/nmkane."""
    env = os.environ.get("NMKANE_CACHE_DIR")
    if env:
        return Path(env)
    return Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "nmkane"


def kernel_dir() -> Path:
    """Where generated and compiled kernels live."""
    return cache_root() / "kernels"
