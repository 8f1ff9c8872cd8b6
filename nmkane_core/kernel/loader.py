"""A model's kernel, loaded or built: the keys that name it and the on-disk cache lookup.

:func:`kernel` returns the compiled kernel (:class:`~nmkane_core.kernel.cmodel.CModel`) and
:class:`~nmkane_core.kernel.info.ModelInfo` for a fingerprint (:func:`fingerprint` of the files
defining a model, or :func:`model_fingerprint` of a model object): from the cache index when it
is there — no sympy needed — otherwise derived, described (:mod:`nmkane_core.kernel.codegen`),
written and loaded.  The description's folder is keyed by a hash of its text
(:func:`source_key`), so the model's library beside it can never hold code of another text.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import sys
import threading
from collections.abc import Callable
from pathlib import Path

from . import core
from .cache import import_kernel, kernel_damage, kernel_dir, write_kernel
from .cmodel import CModel
from .codegen import generate_source
from .info import ModelInfo
from .native import NativeBuildError, report_damaged

__all__ = ["compiled_kernel", "fingerprint", "kernel", "model_fingerprint", "source_key"]

_LOCK = threading.Lock()
_LOADED: dict[str, object] = {}


def source_key(source: str) -> str:
    """The cache folder of a kernel description: a hash of its text and of the loop constants
    the compiled core shares with it (:mod:`nmkane_core.kernel.constants`)."""
    h = hashlib.sha256(source.encode())
    h.update((Path(__file__).parent / "constants.py").read_bytes())
    return h.hexdigest()[:20]


def _import(folder: Path, key: str, source: str | None) -> CModel:
    """Load kernel ``key`` from ``folder``, writing ``source`` there first when given."""
    if source is not None:
        write_kernel(folder, key, source)
    description, library, path = import_kernel(folder, key)
    return CModel(f"nmkane_kernel_{key}", description, library, str(path))


class _Damaged(Exception):
    """A cached description failed its check (already reported): it is generated again."""


def _import_cached(folder: Path, key: str):
    """Load cached kernel ``key`` after checking its text (:func:`~.cache.kernel_damage`).  A
    damaged description is reported in one line and raises :class:`_Damaged`: the caller
    generates it again, and writing it replaces the damaged file atomically.  Raises OSError
    when the description is not there."""
    path = folder / f"nmkane_kernel_{key}.json"
    reason = kernel_damage(folder, key)
    if reason is None:
        try:
            return _import(folder, key, None)
        except (ValueError, KeyError, TypeError) as e:
            reason = f"{type(e).__name__}: {e}"
    report_damaged(path, reason)
    raise _Damaged(reason)


def compiled_kernel(derivation, source: str | None = None):
    """Load (describing and compiling if needed) the compiled kernel of a derivation."""
    if source is None:
        source = generate_source(derivation)
    return _load(source)


def _load(source: str):
    key = source_key(source)
    with _LOCK:
        if key not in _LOADED:
            _LOADED[key] = _import(kernel_dir() / key, key, source)
        return _LOADED[key]


def module_key(module) -> str:
    """The cache key of a loaded kernel (its folder's name)."""
    return module.__name__.removeprefix("nmkane_kernel_")


#: the files that shape a generated kernel: a change in any of them gives every model a new key
_CORE_FILES = (
    "../symbolic/model.py",
    "../symbolic/derivation.py",
    "../symbolic/terms.py",
    "../symbolic/robust.py",  # its thresholds are written into the kernels
    "codegen.py",
    "printing.py",
    "native.py",
    "interface.py",
    "constants.py",
    "info.py",
)


def fingerprint(system_name: str, variant: str, source_files, extra: str = "") -> str | None:
    """A key for a model's kernel that needs no sympy: the text of every file that defines
    the model, of the generator's files, the versions of the tools that generate it, and
    ``extra`` (which function of those files builds the model)."""
    if not source_files:
        return None
    h = hashlib.sha256(_tools_key(system_name, variant).encode())
    h.update(extra.encode())
    for f in sorted(set(map(str, source_files))):
        h.update(Path(f).read_bytes())
    return h.hexdigest()[:24]


def model_fingerprint(system_name: str, variant: str, model) -> str:
    """A key for a model known only as an object (typed interactively): its expressions,
    printed canonically (``srepr``), and the generator's files and tool versions."""
    import sympy as sp

    fields = (
        "q",
        "u",
        "params",
        "C",
        "D",
        "Q",
        "P",
        "nonholonomic",
        "holonomic",
        "u_independent",
        "energy",
        "outputs",
        "q_dependent",
        "monitors",
        "singular_positions",
        "t",
    )
    text = "\0".join(sp.srepr(getattr(model, f, None)) for f in fields)
    h = hashlib.sha256(_tools_key(system_name, variant).encode())
    h.update(text.encode())
    return h.hexdigest()[:24]


def _tools_key(system_name: str, variant: str) -> str:
    from importlib.metadata import version

    h = hashlib.sha256(f"{system_name}\0{variant}\0{sys.version}".encode())
    for dist in ("sympy", "numpy"):
        h.update(version(dist).encode())
    here = Path(__file__).parent
    for f in _CORE_FILES:
        h.update((here / f).read_bytes())
    return h.hexdigest()


def kernel(fp: str | None, derive: Callable[[], object], label: tuple[str, str] = ("", "")) -> tuple[object, ModelInfo]:
    """The kernel module and model info for fingerprint ``fp``, from the disk cache when it
    is there (no sympy needed), otherwise derived, generated and cached.  ``label`` (system,
    variant) is recorded in the index for ``nmkane cache``."""
    index = kernel_dir() / "index" / f"{fp}.json" if fp else None
    if index is not None and index.exists():
        try:
            entry = json.loads(index.read_text())
            key = entry["key"]
            with _LOCK:
                if key not in _LOADED:
                    _LOADED[key] = _import_cached(kernel_dir() / key, key)
                    with contextlib.suppress(OSError):
                        os.utime(index)  # last use, for `nmkane cache prune --unused-days`
                return _LOADED[key], ModelInfo.from_json(json.dumps(entry["info"]))
        except (OSError, KeyError, ValueError, TypeError, _Damaged, NativeBuildError):
            pass  # a damaged entry (said by _import_cached), or a C library that does not build: regenerate below
    core.prepare()  # a first use: the compiler builds the core (if it must) while sympy derives
    d = derive()
    source = generate_source(d)
    module = compiled_kernel(d, source)
    info = ModelInfo.from_derivation(d)
    if index is not None:
        index.parent.mkdir(parents=True, exist_ok=True)
        tmp = index.with_suffix(f".tmp{os.getpid()}")
        tmp.write_text(
            json.dumps(
                {
                    "key": module_key(module),
                    "system": label[0],
                    "variant": label[1],
                    "info": json.loads(info.to_json()),
                }
            )
        )
        os.replace(tmp, index)
    return module, info
