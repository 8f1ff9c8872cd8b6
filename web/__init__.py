"""nmkane web app: the Appell–Hamel mechanism and the sliding particle in viser (``python -m web``)."""
