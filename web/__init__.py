"""nmkane web app: every registered system live in a browser, in viser (``python -m web``)."""
