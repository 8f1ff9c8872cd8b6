"""A large model's straight-line functions compiled by the machine's C compiler.

numba compiles straight-line code slowly: about 10 ms a statement, most of it type inference,
and again in part each time LLVM optimizes a caller that links it — a model with a few
thousand statements in its terms (a closed chain of 81 rods: 81 coordinates, 80 loop
closures) spent over a minute there.  A C compiler takes a second or two for the same code.
So a model whose ``terms`` are too large to paste into the right-hand side
(:data:`~nmkane_core.kernel.codegen.INLINE_TERMS_MAX_STATEMENTS`) gets its model-specific
functions — ``terms``, ``constraint_terms``, ``positions``, ``diagnostics``, ``outputs``, the
same common subexpressions and assignments — printed as C, compiled into a shared library
beside the generated module, and called from the numba code through an external symbol
(``numba.types.ExternalFunction``): numba's cache keeps the callers, which find the symbol by
name once the library is loaded (:func:`load`, at the module's import).  Small models (the
paper's) keep their numba body pasted into the stage loop, which is faster there.

Without a C compiler (``cc``, ``gcc`` or ``clang`` on the PATH, or ``$CC``), or with
``NMKANE_NATIVE=0``, every model is compiled by numba alone, as before.  An expression the C
printer cannot write, or a compiler that fails, does the same for that model.  A cached library
that does not load, or lacks a function (a truncated or overwritten file), is built again
with a one-line notice (:func:`load`).
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

from .printing import c_printer

__all__ = [
    "NativeBuildError",
    "c_function",
    "c_module",
    "compiler",
    "library_damage",
    "load",
    "numba_wrapper",
    "report_damaged",
]

#: -O1: the functions are straight lines (no loops to vectorize); -O2 took half as long again to
#: compile for no measurable gain.  No -ffast-math: NaN and ±inf must come through (the loops'
#: finiteness checks turn them into a status), so only errno is dropped.  -ffp-contract=off: no
#: fused multiply-add where the target has one (gcc's default in GNU C fuses): the same bits on
#: every machine, as the numba code (codegen.FASTMATH)
FLAGS = ("-O1", "-fPIC", "-shared", "-fno-math-errno", "-ffp-contract=off")
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


class NativeBuildError(RuntimeError):
    """The C compiler failed on a generated library (the model is then compiled by numba)."""


def compiler() -> str | None:
    """The C compiler to use, or None (none found, or ``NMKANE_NATIVE=0``)."""
    if os.environ.get("NMKANE_NATIVE", "1") == "0":
        return None
    for name in (os.environ.get("CC"), "cc", "gcc", "clang"):
        if name and (path := shutil.which(name)):
            return path
    return None


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


def numba_wrapper(name: str, args: tuple[str, ...], out: str, tag: str, returns: bool = False) -> str:
    """The numba side of C function ``name``: its external symbol and a function of the same
    name and arguments as the numba block it replaces (arrays passed as contiguous pointers;
    an output array that is not contiguous gets the written copy back)."""
    sym = f"_native_{name}"
    kinds = ", ".join(["types.float64" if a == "t" else "_PD" for a in args] + ["_PD"])
    restype = "types.float64" if returns else "types.void"
    call = ", ".join(["t" if a == "t" else f"np.ascontiguousarray({a}).ctypes" for a in args] + [f"{out}c.ctypes"])
    ret = "_r = " if returns else ""
    lines = [
        f'{sym} = types.ExternalFunction("nmk_{tag}_{name}", {restype}({kinds}))',
        "",
        "",
        '@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")',
        f"def {name}({', '.join([*args, out])}):",
        f"    {out}c = np.ascontiguousarray({out})",
        f"    {ret}{sym}({call})",
        f"    if not {out}.flags.c_contiguous:",
        f"        {out}[:] = {out}c",
    ]
    if returns:
        lines.append("    return _r")
    return "\n".join(lines) + "\n"


def _library(module_file: str, tag: str) -> Path:
    return Path(module_file).with_name(f"native_{tag}.so")


def build(module_file: str, tag: str, source: str, again: bool = False) -> Path:
    """Compile the library of the module at ``module_file`` beside it, unless it is there
    (``again``: replace the one there; atomic: a parallel process sees a whole library).
    Raises :class:`NativeBuildError` with the compiler's message."""
    path = _library(module_file, tag)
    if path.exists() and not again:
        return path
    cc = compiler() or shutil.which("cc") or "cc"  # a cached module asks for its library: any compiler
    with _BUILD_LOCK:
        if path.exists() and not again:
            return path
        path.parent.mkdir(parents=True, exist_ok=True)
        src = path.with_suffix(f".{os.getpid()}.c")
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        src.write_text(source)
        try:
            out = subprocess.run(
                [cc, *FLAGS, "-o", str(tmp), str(src), "-lm"], capture_output=True, text=True, timeout=600
            )
        except (OSError, subprocess.SubprocessError) as e:
            raise NativeBuildError(f"{cc}: {e}") from None
        finally:
            with contextlib.suppress(OSError):
                src.unlink()
        if out.returncode != 0:
            with contextlib.suppress(OSError):
                tmp.unlink()
            raise NativeBuildError(f"{cc} failed on the kernel's C functions: {out.stderr.strip()[-2000:]}")
        os.replace(tmp, path)
    return path


def library_damage(path: Path, source: str | None = None) -> str | None:
    """Why the library at ``path`` cannot be used (it does not load, or lacks a function of its C
    ``source``), or None when it loads whole."""
    try:
        lib = ctypes.CDLL(str(path))
    except OSError as e:
        return str(e).removeprefix(f"{path}: ")
    for name in re.findall(r"\b(nmk_[0-9a-f]+_\w+)\(", source or ""):
        if not hasattr(lib, name):
            return f"no function {name}"
    return None


def load(module_file: str, tag: str, source: str) -> None:
    """Make the symbols of the module's library known to numba's JIT linker (building the
    library first when it is not there yet, and again when the one there is damaged)."""
    import llvmlite.binding as llvm

    path = build(module_file, tag, source)
    reason = library_damage(path, source)
    if reason is not None:
        report_damaged(path, reason)
        path = build(module_file, tag, source, again=True)
        if (reason := library_damage(path, source)) is not None:
            raise NativeBuildError(f"{path}: rebuilt, still {reason}")
    llvm.load_library_permanently(str(path))
