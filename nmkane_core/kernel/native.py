"""A model's straight-line functions compiled by the machine's C compiler.

Each model's ``terms``, ``constraint_terms``, ``positions``, ``diagnostics`` and ``outputs`` —
common subexpressions, then assignments (:class:`~nmkane_core.kernel.codegen.Block`) — are
printed as C (:func:`c_function`), compiled with ``-O1`` into a small shared library beside the
model's description in the kernel cache (:func:`build`: 0.1 s for the paper's models, about a
second for a model of 600 statements), and called by the compiled core through function pointers
(:mod:`nmkane_core.kernel.cmodel`).  A cached library that does not load, or lacks a function (a
truncated or overwritten file), is built again with a one-line notice
(:func:`~nmkane_core.kernel.cache.import_kernel`).  Without a C compiler (``$CC``, ``cc``,
``gcc`` or ``clang``) nothing runs: :func:`compiler_or_fail` says what to install.
"""

from __future__ import annotations

import contextlib
import ctypes
import hashlib
import logging
import os
import re
import shutil
import subprocess
import threading
from pathlib import Path

from ..errors import NmkaneError
from .printing import c_printer

__all__ = [
    "NativeBuildError",
    "c_function",
    "c_module",
    "build",
    "compiler",
    "compiler_or_fail",
    "library_damage",
    "report_damaged",
]

#: -O1: the functions are straight lines (no loops to vectorize); -O2 took half as long again to
#: compile for no measurable gain.  No -ffast-math: NaN and ±inf must come through (the loops'
#: finiteness checks turn them into a status), so only errno is dropped.  -ffp-contract=off: no
#: fused multiply-add where the target has one (gcc's default in GNU C fuses): the same bits on
#: every machine, as the compiled core (kernel.core.FLAGS)
FLAGS = ("-O1", "-fPIC", "-shared", "-fno-math-errno", "-ffp-contract=off")
#: a model with more statements than this is compiled at -O0: gcc's optimizer is what takes the
#: time on long straight lines (a model of 1,055 statements: 0.11 s against 0.64 s;
#: a 40-link chain's: 0.27 s against 1.36 s) and gains little there (its right-hand side 14 %
#: faster at -O1, the chain's 20 s run 5.3 s against 4.5 s); long work runs the model's
#: specialised build anyway (kernel.special, -O3).  The same operations in the same order: the same bits
LARGE_STATEMENTS = 800


def flags(source: str) -> tuple[str, ...]:
    """The compiler flags of a model's C source (:data:`FLAGS`; -O0 for a large one)."""
    if source.count(";") > LARGE_STATEMENTS:
        return ("-O0", *FLAGS[1:])
    return FLAGS


#: the C type of each argument kind of the generated functions
_C_ARGS = {"t": "const double t", "x": "const double *x", "p": "const double *p"}

_BUILD_LOCK = threading.Lock()

#: where the kernel cache says what it did (a damaged entry rebuilt): one line on stderr when
#: nothing configured logging (Python's last-resort handler), the service's log otherwise
log = logging.getLogger("nmkane.kernel")


def report_damaged(path: Path, reason: str) -> None:
    """Say, in one line, that a damaged kernel cache entry (a module, a library) was found and
    is built again (:mod:`nmkane_core.kernel.cache`)."""
    log.warning("nmkane: kernel cache entry %s was damaged (%s); rebuilt", path, reason)


class NativeBuildError(NmkaneError, RuntimeError):
    """No C compiler, or the compiler failed on the core or a model's library."""


def compiler() -> str | None:
    """The C compiler to use ($CC, else cc, gcc or clang on the PATH), or None."""
    for name in (os.environ.get("CC"), "cc", "gcc", "clang"):
        if name and (path := shutil.which(name)):
            return path
    return None


def compiler_or_fail() -> str:
    """:func:`compiler`, or a one-line error that says what to install."""
    cc = compiler()
    if cc is None:
        raise NativeBuildError(
            "no C compiler found ($CC, cc, gcc or clang on the PATH): nmkane compiles its core once and each "
            "model's functions with one; install one (Debian/Ubuntu: apt install gcc; Fedora: dnf install gcc; "
            "macOS: xcode-select --install)"
        )
    return cc


def c_function(name: str, args: tuple[str, ...], out: str, block, returns: str | None = None) -> str:
    """One straight-line C function of a CSE'd block (:class:`~nmkane_core.kernel.codegen.Block`):
    ``args`` among t, x, p, then the output array ``out`` (``double *``); returns ``double``
    when ``returns`` (a name the block assigns) is given.  Raises ValueError for an expression
    C cannot write."""
    printer = c_printer()
    params = ", ".join([_C_ARGS[a] for a in args] + [f"double *{out}"])
    lines = [f"{'double' if returns else 'void'} @PREFIX@{name}({params}) {{"]
    lines += [f"  const double x_{i} = x[{i}];" for i in block.x_used]
    lines += [f"  const double p_{i} = p[{i}];" for i in block.p_used]
    for lo, hi in block.zero_fill:
        lines.append(f"  for (int k_ = {lo}; k_ < {hi}; ++k_) {out}[k_] = 0.0;")
    try:
        for sym, e in block.replacements:
            lines.append(f"  const double {sym} = {printer.doprint(e)};")
        for target, e, comment in block.outputs:
            decl = "double " if "[" not in target else ""
            note = f"  /* {comment} */" if comment else ""
            lines.append(f"  {decl}{target} = {printer.doprint(e)};{note}")
    except Exception as e:  # sympy's printer is strict: a function C does not have
        raise ValueError(f"{name}: not printable as C ({e})") from None
    if returns:
        lines.append(f"  return {returns};")
    lines.append("}")
    return "\n".join(lines) + "\n"


def c_module(functions: list[str]) -> tuple[str, str]:
    """(the library's C source, its tag): the symbols are ``nmk_<tag>_<name>``, the tag a hash
    of the source, so two kernels' libraries loaded into one process never clash."""
    body = "#include <math.h>\n\n" + "\n".join(functions)
    tag = hashlib.sha256(body.encode()).hexdigest()[:16]
    return body.replace("@PREFIX@", f"nmk_{tag}_"), tag


def _library(module_file: str, tag: str) -> Path:
    return Path(module_file).with_name(f"native_{tag}.so")


def build(module_file: str, tag: str, source: str, again: bool = False) -> Path:
    """Compile the library of the module at ``module_file`` beside it, unless it is there
    (``again``: replace the one there; atomic: a parallel process sees a whole library).
    Raises :class:`NativeBuildError` with the compiler's message."""
    path = _library(module_file, tag)
    if path.exists() and not again:
        return path
    cc = compiler_or_fail()
    with _BUILD_LOCK:
        if path.exists() and not again:
            return path
        path.parent.mkdir(parents=True, exist_ok=True)
        src = path.with_suffix(f".{os.getpid()}.c")
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        src.write_text(source)
        try:
            out = subprocess.run(
                [cc, *flags(source), "-o", str(tmp), str(src), "-lm"], capture_output=True, text=True, timeout=600
            )
        except (OSError, subprocess.SubprocessError) as e:
            raise NativeBuildError(f"{cc}: {e}") from None
        finally:
            with contextlib.suppress(OSError):
                src.unlink()
        if out.returncode != 0:
            with contextlib.suppress(OSError):
                tmp.unlink()
            detail = " ".join(out.stderr.split())[-2000:] or f"exit {out.returncode}"
            raise NativeBuildError(f"{cc} failed on the model's C functions: {detail}")
        os.replace(tmp, path)
    return path


def library_damage(path: Path, source: str | None = None, names: tuple[str, ...] = ()) -> str | None:
    """Why the library at ``path`` cannot be used (it does not load, or lacks a function of its C
    ``source`` or one of ``names``), or None when it loads whole."""
    try:
        lib = ctypes.CDLL(str(path))
    except OSError as e:
        return str(e).removeprefix(f"{path}: ")
    for name in (*re.findall(r"\b(nmk_[0-9a-f]+_\w+)\(", source or ""), *names):
        if not hasattr(lib, name):
            return f"no function {name}"
    return None
