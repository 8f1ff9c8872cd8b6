"""``nmkane serve`` and ``nmkane store``: contributed to the ``nmkane`` command through the
entry-point group ``nmkane.commands`` (the core does not import the service).  Light on
import: FastAPI and uvicorn load only when ``serve`` runs."""

from __future__ import annotations

import argparse

from nmkane_core.cli.argtypes import add_systems_option
from nmkane_core.cli.command import Command
from nmkane_core.cli.common import load_plugged_systems
from nmkane_core.errors import InputError, NmkaneError


def _add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--host",
        default="127.0.0.1",
        help="address to bind (default: loopback); another address asks for an access token",
    )
    p.add_argument("--api-port", type=int, default=8000, help="REST API port (0: a free one)")
    p.add_argument("--viser-port", type=int, default=8080, help="3D web app port (0: a free one)")
    p.add_argument("--no-web", action="store_true", help="REST service only")
    p.add_argument(
        "--scene",
        metavar="NAME",
        default=None,
        help="the system the 3D web app opens new browsers on (any registered or plugged-in system)",
    )
    p.add_argument(
        "--allow-host",
        action="append",
        default=[],
        metavar="NAME",
        help="a host name clients may use to reach this server (Host header), besides the "
        "loopback names and the bound address; repeatable",
    )
    p.add_argument(
        "--no-auth",
        action="store_true",
        help="on a non-loopback address, serve without an access token (anyone who can reach "
        "the port can run and delete runs)",
    )
    p.add_argument(
        "--max-sessions",
        type=int,
        default=None,
        metavar="N",
        help="browsers the 3D web app serves at once (default: NMKANE_MAX_SESSIONS or 40)",
    )
    add_systems_option(p)


def _check_address(args: argparse.Namespace) -> None:
    """Ports in [0, 65535] and a host that is an IP address or a name this machine resolves,
    refused with the range before anything starts (99999 bound port 34463, its value modulo
    2¹⁶; -5 and 999.1.1.1 failed as "is the port in use?")."""
    import ipaddress
    import socket

    for option, port in (("--api-port", args.api_port), ("--viser-port", args.viser_port)):
        if not 0 <= port <= 65535:
            raise InputError(option, port, "a port in [0, 65535] (0: a free one)")
    try:
        ipaddress.ip_address(args.host)
        return
    except ValueError:
        pass
    looks_numeric = all(part.isdigit() for part in args.host.split(".")) or ":" in args.host
    if not looks_numeric:
        try:
            socket.getaddrinfo(args.host, None)
            return
        except (OSError, UnicodeError):
            pass
    raise InputError("--host", args.host, "an IPv4 or IPv6 address, or a host name this machine resolves")


def _run(args: argparse.Namespace) -> int:
    _check_address(args)
    load_plugged_systems(args, strict=False)  # a bad systems file: one line, the others still load
    if args.max_sessions is not None and args.max_sessions < 1:
        raise InputError("max_sessions", args.max_sessions, "an integer ≥ 1")
    if args.scene is not None:
        from nmkane_core.run.registry import get_system

        get_system(args.scene, "--scene")  # an unknown name: one line naming the option and the choices
    try:
        from .serve import serve
    except ImportError as e:
        raise NmkaneError(f"the REST service needs its extra ({e}): pip install 'nmkane[service]'") from None
    serve(
        host=args.host,
        api_port=args.api_port,
        viser_port=args.viser_port,
        web=not args.no_web,
        allow_hosts=tuple(args.allow_host),
        auth=not args.no_auth,
        max_sessions=args.max_sessions,
        app_options={"scene": args.scene} if args.scene else None,
    )
    return 0


SERVE = Command("serve", "start the REST service and the 3D web app", _add_arguments, _run, quick_exit=False)


def _add_store_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--db",
        default=None,
        metavar="FILE",
        help="the run store (default: NMKANE_DB, or NMKANE_DATA_DIR/runs.sqlite3, or ./data/runs.sqlite3)",
    )
    sub = p.add_subparsers(dest="action", required=True, metavar="ACTION")
    prune = sub.add_parser("prune", help="delete old runs: all but the newest N, or those older than DAYS")
    which = prune.add_mutually_exclusive_group(required=True)
    which.add_argument("--keep", type=int, metavar="N", help="keep the newest N runs, delete the others")
    which.add_argument(
        "--older-than",
        type=float,
        dest="older_than",
        metavar="DAYS",
        help="delete the runs stored more than DAYS days ago",
    )
    sub.add_parser("info", help="runs stored, their size, and the store's cap")
    sub.add_parser("check", help="read every page of the store: 'ok', or what is damaged and how to recover (exit 2)")


def _store(args: argparse.Namespace) -> int:
    import math
    from pathlib import Path

    from .config import Settings
    from .store import RunStore

    settings = Settings() if args.db is None else Settings(db_path=Path(args.db))
    if args.db is not None and not Path(args.db).exists():
        raise InputError(
            "db", args.db, "an existing run store (an SQLite file written by `nmkane serve`)", "no such file"
        )
    # a store that cannot be opened (a folder, a damaged or read-only file): one line naming the
    # file and what to do, exit 2 (a StoreError is an NmkaneError); info and check only read
    store = RunStore(settings.database, writable=args.action == "prune")
    try:
        if args.action == "info":
            cap = settings.store_cap
            print(
                f"{settings.database}: {store.count():,} runs, {store.size / 1e6:,.1f} MB of rows "
                f"(cap: {cap.max_runs:,} runs, {cap.max_bytes / 1e6:,.0f} MB; when full: {cap.policy})"
            )
            return 0
        if args.action == "check":
            store.check()
            print(f"{settings.database}: ok ({store.count():,} runs, every page read)")
            return 0
        if args.keep is not None and args.keep < 0:
            raise InputError("keep", args.keep, "an integer ≥ 0")
        if args.older_than is not None and not (math.isfinite(args.older_than) and args.older_than >= 0):
            raise InputError("older_than", args.older_than, "a number of days ≥ 0")
        before = store.count()
        gone = store.prune(keep=args.keep, older_than_s=None if args.older_than is None else args.older_than * 86400.0)
        print(f"{settings.database}: deleted {gone:,} of {before:,} runs; {before - gone:,} left")
        return 0
    finally:
        store.close()


STORE = Command(
    "store", "manage the REST service's run store (prune old runs, info, check)", _add_store_arguments, _store
)
