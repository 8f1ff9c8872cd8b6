"""The derived matrices (A1, A2, T and V of (22), (40), (44)) drawn for the teaching panel.

viser 1.1's markdown does not typeset LaTeX (tested: ``$...$`` shows as source), so the
matrices are drawn as images with matplotlib's mathtext, entry by entry (mathtext has no
matrix environment): each entry is simplified once, the sums that occur in denominators
are named n₁, n₂, … (as the paper names its n's, (67)–(76)) and defined under the
matrices, and the grid gets brackets.  A grid wider than the panel can show is drawn entry
by entry, and an entry still too wide is set on lines of whole terms of its sums.  The LaTeX
source is kept for copying.

Symbolic work is slow (about 8 s for the nonlinear model) and holds the GIL, which
would stall the web server's threads, so :func:`panel` runs it in a child process
(``python -m web.matrices SYSTEM VARIANT OUT``, once per model) and caches the result in
memory and on disk under nmkane's cache root (:func:`nmkane_core.kernel.cache.cache_root`), keyed
by the model's kernel key (:meth:`nmkane_core.kernel.built.Built.key`) and this file: a restart shows the
panels at once.  The web app warms the cache in a background thread at startup.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import os
import pickle
import subprocess
import sys
import tempfile
import threading
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from nmkane_core.symbolic.shorten import Budget, within

MATRICES = ("A1", "A2", "T", "V")
#: what a model without A = −J2⁻¹J1 shows instead (redundant constraints: no square J2)
FALLBACK = ("J1", "J2", "Q", "P")
TITLES = {"A1": "A_1", "A2": "A_2", "T": "T", "V": "V", "J1": "J_1", "J2": "J_2", "Q": "Q", "P": "P"}
DPI = 200  # sharp in viser's enlarged view (the image's expand icon)
ICON_PAD = 30  # px of white above a matrix: viser's expand icon sits in the image's top-right corner
FONT_SIZE = 11
PARENT_ENV = "NMKANE_MATRICES_PARENT"  # the child stops when this process is gone
TYPESET_OPS = 250  # an entry still longer than this (sympy count_ops) once simplified is drawn as ⋯
SIMPLIFY_OPS = 400  # entries up to this long are simplified, within a time budget (symbolic.shorten)
#: a matrix drawn wider than this (px, at DPI) is drawn entry by entry, one under another: the
#: panel is about 345 px wide (Example 1's T as a grid: 1,083 px, shown at a third of its size)
WIDE_PX = 800
#: an entry wider than WIDE_PX is set on lines of pieces at most this wide (:func:`_tokens`)
PIECE_PX = 640


@dataclass
class Panel:
    """What the matrices panel shows for one model."""

    system: str
    variant: str
    images: dict[str, np.ndarray]  # name -> RGBA uint8
    where: np.ndarray | None  # the n_k definitions, RGBA uint8 (None if none)
    latex: dict[str, str]  # name -> LaTeX source of the whole matrix
    intro: str  # markdown above the images


_cache: dict[tuple[str, str], Panel] = {}
_locks: dict[tuple[str, str], threading.Lock] = {}
_guard = threading.Lock()


def panel(system: str, variant: str) -> Panel:
    """The panel of a model: from memory, the disk cache, or derived in a subprocess
    (concurrent callers for the same model wait for one computation)."""
    key = (system, variant)
    with _guard:
        if key in _cache:
            return _cache[key]
        lock = _locks.setdefault(key, threading.Lock())
    with lock:
        if key not in _cache:
            path = _disk_path(system, variant)
            p = _load(path)
            if p is None:
                p = _compute(system, variant, path)
            _cache[key] = p
        return _cache[key]


def cached(system: str, variant: str) -> Panel | None:
    return _cache.get((system, variant))


_children: set = set()


def shutdown() -> None:
    """Stop child processes still deriving (the server is stopping)."""
    with _guard:
        children = list(_children)
    for c in children:
        with contextlib.suppress(OSError):
            c.terminate()


def _compute(system: str, variant: str, path: Path | None) -> Panel:
    """Derive and draw in a child process (its sympy work does not hold our GIL)."""
    fd, tmp = tempfile.mkstemp(suffix=".pickle")
    os.close(fd)
    try:
        env = dict(os.environ)
        root = str(Path(__file__).resolve().parents[1])
        env["PYTHONPATH"] = root + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
        from nmkane_core.run import plugins  # the child knows the systems plugged in here (--systems)

        specs = [s for s in env.get(plugins.ENV_VAR, "").split(os.pathsep) if s.strip()]
        specs += [k for k in plugins.loaded_specs() if k not in specs]
        if specs:
            env[plugins.ENV_VAR] = os.pathsep.join(specs)
        env[PARENT_ENV] = str(os.getpid())
        child = subprocess.Popen(
            [sys.executable, "-m", "web.matrices", system, variant, tmp],
            env=env,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
        )
        with _guard:
            _children.add(child)
        try:
            _, err = child.communicate(timeout=900)
        finally:
            with _guard:
                _children.discard(child)
        p = _load(Path(tmp))
        if child.returncode != 0 or p is None:
            raise RuntimeError(
                f"deriving the matrices failed: {(err or '').strip().splitlines()[-1:] or child.returncode}"
            )
        _store(path, p)
        return p
    finally:
        with contextlib.suppress(OSError):
            os.unlink(tmp)


def _disk_path(system: str, variant: str) -> Path | None:
    """The panel's file in nmkane's cache, keyed by the model's kernel key (it changes
    whenever the model does), matplotlib's version and this file; None: not cached."""
    try:
        from nmkane_core import get_system
        from nmkane_core.kernel.built import built
        from nmkane_core.kernel.cache import cache_root

        key = built(get_system(system)).key(variant)
        if key is None:
            return None
        import matplotlib

        h = hashlib.sha256(f"{key}\0{matplotlib.__version__}".encode())
        h.update(Path(__file__).read_bytes())
        return cache_root() / "web-matrices" / f"{system}-{variant}-{h.hexdigest()[:16]}.pickle"
    except Exception:  # no cache: compute every time
        return None


def _load(path: Path | None) -> Panel | None:
    if path is None or not path.exists():
        return None
    try:
        with open(path, "rb") as f:
            p = pickle.load(f)
        return p if isinstance(p, Panel) else None
    except Exception:
        return None


def _store(path: Path | None, p: Panel) -> None:
    if path is None:
        return
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        with open(tmp, "wb") as f:
            pickle.dump(p, f)
        os.replace(tmp, path)
    except OSError:
        pass


# --------------------------------------------------------------------------- algebra
def _nice(e, budget: Budget):
    """A short form of one entry: the shortest of sympy's simplify and a trig-expanded
    cancellation (which finds e.g. −ρ cos θ in the nonlinear model's A1), found within the
    panel's time ``budget`` (else the entry as derived)."""
    import sympy as sp

    if e.is_number or sp.count_ops(e) > SIMPLIFY_OPS:
        return e

    def forms():
        s = sp.simplify(e)
        out = [e, s]
        try:
            c = sp.cancel(sp.expand_trig(s))
            out += [c, sp.factor(c)]
        except Exception:  # pragma: no cover - sympy corner cases
            pass
        return out

    return min(within(budget.seconds(), forms, [e]), key=lambda f: (sp.count_ops(f), len(str(f))))


def _abbreviate(mats: dict):
    """Name the sums found in denominators n_1, n_2, … across all matrices."""
    import sympy as sp

    found: list = []
    for M in mats.values():
        for e in M:
            _, den = sp.fraction(sp.together(e))
            for f in sp.Mul.make_args(sp.factor_terms(den)):
                base = f.base if f.is_Pow else f
                if base.is_Add and base not in found:
                    found.append(base)
    names = [sp.Symbol(f"n_{i + 1}") for i in range(len(found))]
    subs = dict(zip(found, names, strict=True))
    short = {k: M.applyfunc(lambda e: sp.factor_terms(sp.together(e)).subs(subs)) for k, M in mats.items()}
    return short, list(zip(names, found, strict=True))


def _build(system: str, variant: str) -> Panel:
    import sympy as sp

    from nmkane_core import get_system
    from nmkane_core.errors import NotDefined
    from nmkane_core.kernel.built import built

    core = get_system(system)
    d = built(core).derivation(variant)
    missing = None
    try:
        raw = {name: d.matrix(name) for name in MATRICES}
    except NotDefined as e:
        missing = str(e)
        raw = {name: d.matrix(name) for name in FALLBACK}
    shown = tuple(raw)
    elided = sp.Dummy("elided")  # stands for an entry too long to typeset
    # the whole panel's (nmkane_core.symbolic.shorten); what it leaves unsimplified on a loaded
    # machine is broken across lines (_tokens)
    budget = Budget()
    nice = {name: M.applyfunc(lambda e: _nice(e, budget)) for name, M in raw.items()}
    longest = max((sp.count_ops(e) for M in nice.values() for e in M), default=0)
    mats = {name: M.applyfunc(lambda e: elided if sp.count_ops(e) > TYPESET_OPS else e) for name, M in nice.items()}
    short, defs = _abbreviate(mats)

    def tex(e) -> str:
        if e == elided:
            return r"\cdots"
        return sp.latex(e, fold_func_brackets=True).replace(r"\frac", r"\dfrac")

    images = {
        name: _matrix_or_entries(
            TITLES[name],
            [[tex(short[name][i, j]) for j in range(short[name].cols)] for i in range(short[name].rows)],
            lambda i, j, M=short[name]: lambda: _tokens(M[i, j], tex),
        )
        for name in shown
        if short[name].rows and short[name].cols
    }
    where_image = _lines_image([f"{tex(n)} = {tex(e)}" for n, e in defs]) if defs else None
    where = [f"{tex(n)} = {tex(e)}" for n, e in defs]
    latex = {
        name: f"{TITLES[name]} = {sp.latex(short[name], fold_func_brackets=True)}"
        if all(e != elided for e in short[name])
        else f"% {TITLES[name]}: too long to show; `nmkane matrices {system} --{core.option} {variant}` prints it"
        for name in shown
    }
    if where:
        latex["where"] = r"\text{where } " + r",\quad ".join(where)
    intro = (
        f"**{system}, {variant}** — nonminimal equations T u̇ = V̂ (44), with "
        f"A1 = [−A  I] (22), A2 = [I  Aᵀ] (40), T = [A1; A2 Q] and V = [B; A2 P] (44), where "
        f"u̇_D = A u̇_I + B is the constraints' acceleration form (20) and P = F − L (43) "
        f"(a run adds the Baumgarte terms to B: V̂ of (110)); speeds ordered "
        f"[u_I, u_D] = ({', '.join(str(s) for s in d.u_perm)}){speed_names(built(get_system(system)).model(variant))}."
    )
    if missing:
        intro += f" Shown instead: J1, J2, Q and P (43). {missing[0].upper()}{missing[1:]}."
    if longest > TYPESET_OPS:
        intro += (
            f" Entries drawn as ⋯ are too long to typeset (the longest has {longest:,} operations); "
            f"`nmkane matrices {system}` prints them in full."
        )
    return Panel(system, variant, images, where_image, latex, intro)


def speed_names(model) -> str:
    """The text "; u1 = ẋ, u2 = ẏ" when the speeds are the coordinates' rates (q̇ = u), else ""."""
    import sympy as sp

    if sp.eye(len(model.q)) != model.C or any(v != 0 for v in model.D):
        return ""
    return "; " + ", ".join(f"{sp.pretty(u)} = {sp.pretty(q)}\u0307" for u, q in zip(model.u, model.q, strict=True))


# --------------------------------------------------------------------------- drawing
def _tex_image(tex: str, fontsize: int = FONT_SIZE) -> np.ndarray:
    """One mathtext expression as a grey-level ink image (1 = ink), float (h, w)."""
    from matplotlib.font_manager import FontProperties
    from matplotlib.image import imread
    from matplotlib.mathtext import math_to_image

    buf = io.BytesIO()
    math_to_image(f"${tex}$", buf, prop=FontProperties(size=fontsize), dpi=DPI, format="png")
    buf.seek(0)
    img = imread(buf)
    ink = 1.0 - img[..., :3].mean(axis=-1)  # black on white → ink
    if img.shape[-1] == 4:
        ink = ink * img[..., 3]
    return ink.astype(np.float32)


def _blit(canvas: np.ndarray, ink: np.ndarray, top: int, left: int) -> None:
    h, w = ink.shape
    canvas[top : top + h, left : left + w] = np.maximum(canvas[top : top + h, left : left + w], ink)


#: ink levels of :func:`_to_rgba`'s table (finer than the 256 of the PNGs the ink comes from)
INK_LEVELS = 4096


def _to_rgba(ink: np.ndarray, color=(20, 20, 30)) -> np.ndarray:
    """Ink on an opaque white background (readable in light and dark panels alike), through a
    table of the blended colours: a closed loop's matrices are millions of pixels (one Q of the
    catalogue: 475 × 29,073), where blending each pixel in floating point took 9.0 s of its 30 s
    panel (the table: 1.9 s for its three matrices; the colours agree within one level of 255)."""
    level = np.linspace(0.0, 1.0, INK_LEVELS + 1)[:, None]
    table = np.empty((INK_LEVELS + 1, 4), np.uint8)
    table[:, :3] = ((1 - level) * 255 + level * np.array(color, float)).clip(0, 255).astype(np.uint8)
    table[:, 3] = 255
    return table[np.rint(np.clip(ink, 0.0, 1.0) * INK_LEVELS).astype(np.intp)]


def _matrix_image(title: str, cells: list[list[str]], pad: int = 10, gap: int = 16, vgap: int = 10) -> np.ndarray:
    inks = [[_tex_image(c) for c in row] for row in cells]
    name = _tex_image(f"{title} =", FONT_SIZE + 1)
    rows, cols = len(inks), len(inks[0])
    row_h = [max(i.shape[0] for i in row) for row in inks]
    col_w = [max(inks[r][c].shape[1] for r in range(rows)) for c in range(cols)]
    grid_h = sum(row_h) + vgap * (rows - 1)
    grid_w = sum(col_w) + gap * (cols - 1)
    br = 10  # bracket width
    H = grid_h + 2 * pad
    W = pad + name.shape[1] + 8 + br + 6 + grid_w + 6 + br + pad
    canvas = np.zeros((H, W), np.float32)
    _blit(canvas, name, (H - name.shape[0]) // 2, pad)
    x0 = pad + name.shape[1] + 8
    for xb, hook in ((x0, 1), (x0 + br + 6 + grid_w + 6 + br - 2, -1)):  # [ and ]
        canvas[pad - 4 : pad + grid_h + 4, xb : xb + 2] = 1.0
        xs = slice(xb, xb + br) if hook == 1 else slice(xb - br + 2, xb + 2)
        canvas[pad - 4 : pad - 2, xs] = 1.0
        canvas[pad + grid_h + 2 : pad + grid_h + 4, xs] = 1.0
    top = pad
    for r in range(rows):
        left = x0 + br + 6
        for c in range(cols):
            ink = inks[r][c]
            _blit(canvas, ink, top + (row_h[r] - ink.shape[0]) // 2, left + (col_w[c] - ink.shape[1]) // 2)
            left += col_w[c] + gap
        top += row_h[r] + vgap
    return _to_rgba(np.pad(canvas, ((ICON_PAD, 0), (0, 0))))


def _matrix_or_entries(title: str, cells: list[list[str]], pieces=None) -> np.ndarray:
    """The matrix as a grid (:func:`_matrix_image`), or, wider than :data:`WIDE_PX`, its nonzero
    entries one under another (``T_{ij} = …``, the zeros counted on the first line): legible in
    the narrow panel, each entry at its own size; an entry still wider is broken across lines
    at the terms of its sums (``pieces(i, j)``: a function giving its :func:`_tokens`)."""
    grid = _matrix_image(title, cells)
    if grid.shape[1] <= WIDE_PX:
        return grid
    entries = [(i, j, c) for i, row in enumerate(cells) for j, c in enumerate(row) if c.strip() != "0"]
    zeros = sum(len(row) for row in cells) - len(entries)
    head = rf"{title}:\ {len(cells)} \times {len(cells[0])},\ \mathrm{{{zeros}\ zeros\ not\ shown}}"
    lines = [head]
    for i, j, c in entries:
        lhs = f"{{{title}}}_{{{i + 1}{j + 1}}}"  # {J_1}_{11}
        lines += _broken(lhs, c, pieces(i, j) if pieces is not None else None)
    return np.pad(_lines_image(lines), ((ICON_PAD, 0), (0, 0), (0, 0)), constant_values=255)


def _split(e, tex) -> tuple[bool, str, list, str] | None:
    """An entry as (negative, opener, terms, closer): the terms of the sum in its numerator (the
    numerator, or its largest sum factor), the rest of it before them as ``factor/denominator (``
    and ``)`` after; None when it has no sum to break at."""
    import sympy as sp

    num, den = sp.fraction(e)
    negative = bool(num.could_extract_minus_sign())
    num = -num if negative else num
    if num.is_Add:
        rest, body = [], num
    elif num.is_Mul and any(f.is_Add for f in num.args):
        body = max((f for f in num.args if f.is_Add), key=sp.count_ops)
        rest = [f for f in num.args if f is not body]
    else:
        return None
    factor = sp.Mul(*rest)
    if factor == 1 and den == 1:
        opener = "(" if negative else ""
    else:
        top = f"({tex(factor)})" if factor.is_Add and den == 1 else tex(factor)  # a sum times (…): in brackets
        opener = (top if den == 1 else rf"\dfrac{{{top}}}{{{tex(den)}}}") + r"\,("
    return negative, opener, list(sp.Add.make_args(body)), ")" if opener else ""


def _tokens(e, tex, lead: str = "") -> list[str]:
    """The pieces of ``e`` (``lead``: the sign it is written with, "", "+" or "-") to set on lines
    of at most :data:`WIDE_PX`: ``e`` whole when it is at most :data:`PIECE_PX` wide (a line's
    indent and left side take the rest) or has no sum to break at, else, in turn, the pieces of
    the terms of its sum (:func:`_split`)."""
    whole = f"{lead} {tex(e)}".strip()
    parts = None if _tex_image(whole).shape[1] <= PIECE_PX else _split(e, tex)
    if parts is None:
        return [whole]
    negative, opener, terms, closer = parts
    sign = {"": "-", "+": "-", "-": "+"}[lead] if negative else lead
    out: list[str] = []
    for k, t in enumerate(terms):
        minus = bool(t.could_extract_minus_sign())
        out += _tokens(-t if minus else t, tex, "-" if minus else "+" if k else "")
    out[-1] += closer
    if opener:  # a piece of its own: the packing may start the first term on the next line
        return [f"{sign} {opener}".strip(), *out]
    out[0] = f"{sign} {out[0]}".strip()
    return out


def _broken(lhs: str, tex: str, tokens) -> list[str]:
    """``lhs = tex`` as one line, or, wider than :data:`WIDE_PX`, as lines of the pieces
    ``tokens()`` gives (:func:`_tokens`), the later lines indented."""
    one = f"{lhs} = {tex}"
    if tokens is None or _tex_image(one).shape[1] <= WIDE_PX:
        return [one]
    pieces = tokens()
    lines, line = [], f"{lhs} = {pieces[0]}"
    for piece in pieces[1:]:
        longer = f"{line} {piece}"
        if _tex_image(longer).shape[1] > WIDE_PX:
            lines.append(line)
            longer = rf"\qquad {piece}"
        line = longer
    return [*lines, line]


def _lines_image(lines: list[str], pad: int = 12, vgap: int = 10) -> np.ndarray:
    inks = [_tex_image(s) for s in lines]
    H = sum(i.shape[0] for i in inks) + vgap * (len(inks) - 1) + 2 * pad
    W = max(i.shape[1] for i in inks) + 2 * pad
    canvas = np.zeros((H, W), np.float32)
    top = pad
    for ink in inks:
        _blit(canvas, ink, top, pad)
        top += ink.shape[0] + vgap
    return _to_rgba(canvas)


if __name__ == "__main__":  # the child process of _compute: SYSTEM VARIANT OUT
    from web import matrices as _module  # pickle web.matrices.Panel, not __main__.Panel

    _system, _variant, _out = sys.argv[1:4]
    _parent = int(os.environ.get(PARENT_ENV) or os.getppid())

    def _watch_parent() -> None:  # the server died (SIGKILL, crash): do not derive for nobody
        import time

        while os.getppid() == _parent:
            time.sleep(1.0)
        os._exit(3)

    threading.Thread(target=_watch_parent, daemon=True).start()
    with open(_out, "wb") as _f:
        pickle.dump(_module._build(_system, _variant), _f)
