"""``nmkane stability SYSTEM``: eigenvalues of the linearized motion against the value a
system declares to sweep (a vehicle's forward speed), the values where the stability changes beside
published ones, and optionally the figure (see :mod:`nmkane_core.analysis.eigensweep`)."""

from __future__ import annotations

import argparse
import json

from .argtypes import add_systems_option, assignment
from .command import Command
from .common import load_plugged_systems


def _range(text: str) -> tuple[float, float, int]:
    try:
        a, b, n = text.split(":")
        out = (float(a), float(b), int(n))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected START:STOP:COUNT, e.g. 0:10:101") from None
    if not (out[2] >= 2 and out[0] < out[1]) or out[2] > 10_000:
        raise argparse.ArgumentTypeError(f"{text!r}: START < STOP and 2 ≤ COUNT ≤ 10000")
    return out


def _add(p: argparse.ArgumentParser) -> None:
    p.add_argument("system", metavar="SYSTEM")
    add_systems_option(p)
    p.add_argument("--over", type=_range, default=None, metavar="START:STOP:COUNT", help="the swept values")
    p.add_argument(
        "--set", type=assignment, action="append", default=[], metavar="NAME=VALUE", help="a physical parameter"
    )
    p.add_argument("--out", default=None, metavar="FILE.png", help="draw the eigenvalues against the swept value")
    p.add_argument("--json", action="store_true", help="machine-readable output")


def plot(system, rows: list[dict], found: list[dict], path: str) -> None:
    """Real and imaginary parts against the swept value, crossings and references marked."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    st = system.stability
    v = np.array([r["value"] for r in rows])
    ev = np.array([[complex(a, b) for a, b in r["eigenvalues"]] for r in rows])
    fig, ax = plt.subplots(figsize=(8, 5.5))
    for j in range(ev.shape[1]):
        ax.plot(v, ev[:, j].real, ".", color="k", ms=3, label="real part" if j == 0 else None)
        im = np.where(np.abs(ev[:, j].imag) > 1e-9, np.abs(ev[:, j].imag), np.nan)
        ax.plot(v, im, ".", color="tab:blue", ms=3, label="|imaginary part|" if j == 0 else None)
    ax.axhline(0, color="0.4", lw=0.8)
    for c in found:
        ax.axvline(c["value"], color="tab:green", lw=1.2)
        ax.annotate(
            f"{c['name'] or c['kind']} {c['value']:.6f}",
            (c["value"], 0),
            xytext=(4, 40 if c["kind"] == "complex" else -60),
            textcoords="offset points",
            color="tab:green",
            rotation=90,
        )
    for name, ref in st.reference.items():
        ax.axvline(ref, color="tab:red", ls=":", lw=1.2)
        ax.annotate(
            f"{name} (published) {ref:.6f}",
            (ref, 0),
            xytext=(-12, 40),
            textcoords="offset points",
            color="tab:red",
            rotation=90,
            fontsize=8,
        )
    fast = st.names.get("fast")
    if fast:
        low = ev.real.min(axis=1)  # the most negative real part: where it is about −8, inside the axes
        i = int(np.argmin(np.abs(low + 8.0)))
        ax.annotate(fast, (v[i], low[i]), xytext=(8, 0), textcoords="offset points")
    lo = max(-10.0, float(np.nanmin(ev.real)))
    ax.set_ylim(lo, max(10.0, float(np.nanmax(np.abs(ev.imag)))) if lo > -10 else 10.0)
    ax.set_xlabel(f"{st.over} [{st.unit}]")
    ax.set_ylabel("eigenvalue [1/s]")
    ax.set_title(f"{system.title or system.name}: eigenvalues of {', '.join(st.keep)}")
    ax.legend(loc="lower left")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _run(args: argparse.Namespace) -> int:
    import numpy as np

    from ..analysis.eigensweep import crossings, sweep
    from ..errors import NmkaneError
    from ..run.registry import get_system

    load_plugged_systems(args)
    system = get_system(args.system)
    params = dict(args.set)
    st = system.stability
    if st is None:
        raise NmkaneError(f"{system.name} declares no stability sweep (System(stability=Stability(...)))")
    a, b, n = args.over or (st.start, st.stop, st.count)
    rows = sweep(system, np.linspace(a, b, n), params)
    found = crossings(system, rows, params)
    if args.out:
        try:
            plot(system, rows, found, args.out)
        except ImportError:
            raise NmkaneError("--out needs matplotlib: pip install 'nmkane[figures]'") from None
    if args.json:
        print(json.dumps({"over": st.over, "unit": st.unit, "rows": rows, "crossings": found}, indent=2))
        return 0
    print(f"{st.over} [{st.unit}]  eigenvalues of {', '.join(st.keep)} (re ± im i)")
    for r in rows:
        print(f"{r['value']:10.4f}  " + "  ".join(f"{re:+10.5f}{im:+9.5f}i" for re, im in r["eigenvalues"]))
    for c in found:
        ref = c["reference"]
        extra = f"   published {ref:.14g}, relative difference {abs(c['value'] - ref) / abs(ref):.1e}" if ref else ""
        print(f"{c['name'] or c['kind']} {st.over}: {c['value']:.14g} {st.unit}{extra}")
    if args.out:
        print(f"figure: {args.out}")
    return 0


COMMAND = Command(
    "stability",
    "eigenvalues of the linearized motion against the value a system declares to sweep (e.g. a forward speed)",
    _add,
    _run,
)
