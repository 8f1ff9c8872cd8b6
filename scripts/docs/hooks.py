"""MkDocs hook: the built site fetches nothing from another host (it must work offline).

A page whose HTML loads a script, a stylesheet, a font or an image from ``http(s)://`` fails
the build (links a reader may follow are fine)."""

from __future__ import annotations

import re

from mkdocs.exceptions import PluginError

FETCH = re.compile(
    r"<(?:script|img|iframe|source)\b[^>]*\bsrc=\"(https?://[^\"]+)|<link\b[^>]*\bhref=\"(https?://[^\"]+)"
)


def on_post_page(output: str, page, config) -> str:
    m = FETCH.search(output)
    if m:
        raise PluginError(
            f"{page.file.src_uri}: the page would fetch {m.group(1) or m.group(2)} (the site must work offline)"
        )
    return output
