"""``nmkane cache info|clear|prune``: the on-disk kernel cache (see :mod:`nmkane_core.kernel.cache`)."""

from __future__ import annotations

import argparse
import contextlib
import json

from .argtypes import finite
from .command import Command


def _add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "action",
        choices=("info", "clear", "prune"),
        help="info: size and entries; clear: remove everything; "
        "prune: remove kernels whose sources changed, damaged kernels and kernels nothing uses",
    )
    p.add_argument(
        "--unused-days",
        type=finite,
        dest="unused_days",
        help="prune: also remove kernels not loaded for this many days",
    )
    p.add_argument("--json", action="store_true", help="machine-readable output")


def _mb(n: int) -> str:
    return f"{n / 1e6:.1f} MB"


def _current_fingerprints() -> dict:
    from ..kernel.built import built
    from ..run.registry import get_system, system_names

    out = {}
    for name in system_names():
        s = get_system(name)
        for v in s.variants:
            out[(s.name, v)] = built(s).key(v)
    return out


def _run(args: argparse.Namespace) -> int:
    from ..kernel import cache, special

    if args.action == "info":
        data = cache.info()
        if args.json:
            print(json.dumps(data, indent=2))
            return 0
        print(f"cache    {data['root']}  ({_mb(data['bytes'])})")
        print(f"kernels  {len(data['kernels'])} compiled, {len(data['entries'])} index entries")
        for e in data["entries"]:
            print(f"  {e['system'] or '?'} / {e['variant'] or '?'}  -> kernel {e['key']}")
        for k in data["kernels"]:
            if k.get("damaged"):
                d = k["damaged"]
                print(f"damaged  {d['path']} ({d['reason']}): `nmkane cache prune` removes it")
        for name, size in data["other"].items():
            print(f"{name:8s} {_mb(size)}")
        return 0
    if args.action == "clear":
        freed = cache.clear()
        print(json.dumps({"bytes": freed}) if args.json else f"cleared {_mb(freed)}")
        return 0
    done = cache.prune(_current_fingerprints(), args.unused_days)
    done["builds"] = []
    for path in special.stale_builds(cache.cache_root()):  # the core's and models' builds of older sources
        with contextlib.suppress(OSError):
            done["bytes"] += path.stat().st_size
            path.unlink()
            done["builds"].append(str(path))
    if args.json:
        print(json.dumps(done, indent=2))
    else:
        for e in done["entries"]:
            print(f"removed {e['system']} / {e['variant']} ({e['reason']})")
        for d in done["damaged"]:
            print(f"removed damaged {d['path']} ({d['reason']})")
        print(
            f"pruned {len(done['entries'])} index entries and {len(done['kernels'])} kernels "
            f"({len(done['damaged'])} damaged) and {len(done['builds'])} compiled builds of older sources, "
            f"{_mb(done['bytes'])} freed"
        )
    return 0


COMMAND = Command("cache", "show, prune or clear the compiled-kernel cache", _add_arguments, _run)
