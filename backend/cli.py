"""``nmkane serve``: contributed to the ``nmkane`` command through the entry-point group
``nmkane.commands`` (the core does not import the service).  Light on import: FastAPI and
uvicorn load only when the command runs."""

from __future__ import annotations

import argparse

from nmkane_core.cli.command import Command
from nmkane_core.cli.common import add_systems_option, load_plugged_systems
from nmkane_core.errors import NmkaneError


def _add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--host", default="127.0.0.1", help="address to bind (default: loopback)")
    p.add_argument("--api-port", type=int, default=8000, help="REST API port (0: a free one)")
    p.add_argument("--viser-port", type=int, default=8080, help="3D web app port (0: a free one)")
    p.add_argument("--no-web", action="store_true", help="REST service only")
    p.add_argument("--scene", metavar="NAME", default=None,
                   help="the system the 3D web app opens new browsers on (any registered or plugged-in system)")
    add_systems_option(p)


def _run(args: argparse.Namespace) -> int:
    load_plugged_systems(args, strict=False)     # a bad systems file: one line, the others still load
    if args.scene is not None:
        from nmkane_core.registry import get_system

        get_system(args.scene, "--scene")        # an unknown name: one line naming the option and the choices
    try:
        from .serve import serve
    except ImportError as e:
        raise NmkaneError(f"the REST service needs its extra ({e}): pip install 'nmkane[service]'") from None
    serve(host=args.host, api_port=args.api_port, viser_port=args.viser_port, web=not args.no_web,
          app_options={"scene": args.scene} if args.scene else None)
    return 0


SERVE = Command("serve", "start the REST service and the 3D web app", _add_arguments, _run, quick_exit=False)
