"""``nmkane export SYSTEM [run options] --out FILE.html``: one run as a self-contained page
(:mod:`web.export`; ``--out FILE.gif``: a film of it, :mod:`web.export_gif`).

Contributed to the ``nmkane`` command through the entry-point group ``nmkane.commands`` (the
core does not import the web app).  The run options are ``nmkane run``'s
(:func:`nmkane_core.cli.run_cmd.add_simulation_arguments`, made from
:class:`~nmkane_core.schema.RunSettings`).  Light on import: viser and matplotlib load only
when the export runs.

Exit code 0 when the run ended ``ok`` (or at a declared event), 1 when it ended otherwise
(the file is written either way: it shows how it failed), 2 on bad input.
"""

from __future__ import annotations

import argparse
import time

from nmkane_core.cli.command import Command
from nmkane_core.cli.run_cmd import add_simulation_arguments, simulate_from_args
from nmkane_core.errors import NmkaneError


def _add_arguments(p: argparse.ArgumentParser) -> None:
    add_simulation_arguments(p)
    p.add_argument(
        "--out",
        required=True,
        metavar="FILE.html",
        help="the page to write: one HTML file that plays the run's 3D animation and shows its plots, "
        "offline (no server, nothing fetched); FILE.gif: a film of that page (needs Chromium and Playwright)",
    )


def _run(args: argparse.Namespace) -> int:
    from .export import GIF, check_out, write

    wanted = check_out(args.out)  # a bad file name is refused before the run
    run = simulate_from_args(args)
    t0 = time.perf_counter()
    try:
        if wanted.suffix.lower() == GIF:
            from .export_gif import write_gif

            out = write_gif(run, wanted)
        else:
            out = write(run, wanted)
    except ImportError as e:  # viser and matplotlib come with the web extra
        raise NmkaneError(f"export needs the web app's extra ({e}): pip install 'nmkane[web]'") from None
    size = out.stat().st_size
    print(
        f"{run.status}: {run.summary['message']} -> {out} "
        f"({size / 1e6:.2f} MB, written in {time.perf_counter() - t0:.1f} s)"
    )
    return 0 if run.status in ("ok", "event") else 1


EXPORT = Command(
    "export",
    "simulate a system and write one self-contained HTML page that plays it offline",
    _add_arguments,
    _run,
)
