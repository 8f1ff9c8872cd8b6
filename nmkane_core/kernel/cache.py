"""Where nmkane keeps what it computes once: the on-disk cache folders.

``$NMKANE_CACHE_DIR`` (or ``$XDG_CACHE_HOME/nmkane``, or ``~/.cache/nmkane``) is the root;
compiled kernels live under ``kernels/``; other faces (the web app's rendered matrices)
keep their own sub-folders next to it, keyed by :meth:`nmkane_core.System.kernel_key`.
"""

from __future__ import annotations

import ctypes
import hashlib
import inspect
import json
import os
import threading
from collections.abc import Callable
from pathlib import Path

from .native import library_damage

__all__ = [
    "cache_root",
    "declared_data",
    "import_kernel",
    "kernel_damage",
    "kernel_dir",
    "write_kernel",
]


def cache_root() -> Path:
    """The root of nmkane's cache: $NMKANE_CACHE_DIR, else $XDG_CACHE_HOME/nmkane, else ~/.cache/nmkane."""
    env = os.environ.get("NMKANE_CACHE_DIR")
    if env:
        return Path(env)
    return Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "nmkane"


def declared_data(
    key: str | None, declaration, kind: str, generator: str, version: str, build: Callable[[], dict]
) -> dict:
    """JSON data generated from a system's declaration (its visuals, its events): read from
    ``<cache root>/KIND/``, or ``build()`` (sympy work) and stored there.  The file is keyed by
    ``key`` (the system's kernel key, :meth:`nmkane_core.kernel.built.Built.key`), the file
    defining ``declaration`` and the declaration itself (:func:`_identity`), the ``generator``
    module's file and its ``version``; a declaration with no file (defined interactively) is
    never cached."""
    path = None
    try:
        src = inspect.getsourcefile(declaration)
    except TypeError:
        src = None
    identity = _identity(declaration)
    if key is not None and src is not None and not src.startswith("<") and identity is not None:
        h = hashlib.sha256(f"{key}\0{version}\0{identity}".encode())
        h.update(Path(src).read_bytes())
        h.update(Path(generator).read_bytes())
        path = cache_root() / kind / f"{h.hexdigest()[:24]}.json"
        try:
            return json.loads(path.read_text())
        except (OSError, ValueError):
            pass
    data = build()
    if path is not None:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            tmp = path.with_suffix(f".{os.getpid()}.{threading.get_ident()}.tmp")
            tmp.write_text(json.dumps(data))
            tmp.replace(path)
        except OSError:
            pass
    return data


_PLAIN = (bool, int, float, str, bytes, type(None))


def _code_text(code) -> str:
    """A code object as text that is the same in every process (marshal's output depends on
    reference counts; a frozenset's order on string hashing)."""
    consts = []
    for c in code.co_consts:
        if hasattr(c, "co_code"):
            consts.append(_code_text(c))
        elif isinstance(c, frozenset):
            consts.append(repr(sorted(map(repr, c))))
        else:
            consts.append(repr(c))
    return repr((code.co_code.hex(), code.co_names, code.co_varnames, consts))


def _identity(declaration) -> str | None:
    """What tells a declaration from the others in its file: its qualified name, its code and
    the values it closes over (``_visuals(N)``'s N).  Two declarations of one file under one
    system name shared a cache file: the first one's data answered for the second (a shuffled
    test run).  None — never cached — when a closed-over value cannot be written down."""
    code = getattr(declaration, "__code__", None)
    if code is None:  # not a function: nothing that tells it apart
        return None
    # its compiled code (not inspect.getsource: a declaration compiled from text that is not a
    # Python file, a docs page's block, made the tokenizer raise)
    parts = [declaration.__qualname__, _code_text(code)]
    for cell in getattr(declaration, "__closure__", None) or ():
        try:
            value = cell.cell_contents
        except ValueError:  # a cell not filled yet
            continue
        items = value if isinstance(value, tuple) else (value,)
        if not all(isinstance(v, _PLAIN) for v in items):
            return None
        parts.append(repr(value))
    return "\0".join(parts)


def kernel_dir() -> Path:
    """Where generated and compiled kernels live."""
    return cache_root() / "kernels"


def _kernel_file(folder: Path, key: str) -> Path:
    return folder / f"nmkane_kernel_{key}.json"


#: the first line of a cached description: the SHA-256 of the rest of its text (a truncated or
#: overwritten file is found before it is read)
_CHECKSUM = "# nmkane-sha256: "


def _sha256(text: str) -> str:
    return hashlib.sha256(text.encode()).hexdigest()


def write_kernel(folder: Path, key: str, source: str) -> bool:
    """Write a kernel description, its checksum on its first line, unless the same text is there
    (a damaged file is replaced); True if written."""
    path = _kernel_file(folder, key)
    text = f"{_CHECKSUM}{_sha256(source)}\n{source}"
    try:
        if path.read_text() == text:
            return False
    except (OSError, ValueError):  # not there, or not text
        pass
    folder.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(f".tmp{os.getpid()}")
    tmp.write_text(text)
    os.replace(tmp, path)  # atomic: a parallel process never sees half a file
    return True


def _read(folder: Path, key: str) -> tuple[str | None, str]:
    """(why the cached description of kernel ``key`` cannot be used, or None; its text)."""
    path = _kernel_file(folder, key)
    try:
        text = path.read_text()
    except ValueError:
        return "not text", ""
    head, newline, body = text.partition("\n")
    if not head.startswith(_CHECKSUM):
        return "no checksum", ""
    if not newline or _sha256(body) != head.removeprefix(_CHECKSUM):
        return f"checksum mismatch, {len(text.encode())} bytes", ""
    return None, body


def kernel_damage(folder: Path, key: str) -> str | None:
    """Why the cached description of kernel ``key`` in ``folder`` cannot be used (damaged:
    truncated, overwritten), or None when it is whole.  Raises OSError when the file cannot be
    read (missing)."""
    return _read(folder, key)[0]


def import_kernel(folder: Path, key: str) -> tuple[dict, ctypes.CDLL, Path]:
    """The kernel written by :func:`write_kernel`: (its description, the model's library loaded —
    compiled first when it is not there, again when the one there is damaged — the description's path)."""
    import json

    from .native import build, report_damaged

    reason, body = _read(folder, key)
    if reason is not None:
        raise ValueError(f"{_kernel_file(folder, key)}: {reason}")
    description = json.loads(body)
    path = _kernel_file(folder, key)
    tag, source = description["tag"], description["c_source"]
    lib = build(str(path), tag, source)
    if (reason := library_damage(lib, source)) is not None:
        report_damaged(lib, reason)
        lib = build(str(path), tag, source, again=True)
        if (reason := library_damage(lib, source)) is not None:
            raise OSError(f"{lib}: rebuilt, still {reason}")
    return description, ctypes.CDLL(str(lib)), path


# --------------------------------------------------------------------------- housekeeping
def _size(path: Path) -> int:
    if path.is_file():
        return path.stat().st_size
    return sum(f.stat().st_size for f in path.rglob("*") if f.is_file())


def _entries() -> list[dict]:
    """The kernel index: one entry per cached (system, variant, fingerprint)."""
    import json

    out = []
    for f in sorted((kernel_dir() / "index").glob("*.json")):
        try:
            entry = json.loads(f.read_text())
        except (OSError, ValueError):
            entry = {}
        out.append(
            {
                "path": f,
                "fingerprint": f.stem,
                "key": entry.get("key"),
                "system": entry.get("system"),
                "variant": entry.get("variant"),
                "last_used": f.stat().st_mtime,
            }
        )
    return out


def _kernel_folders() -> list[Path]:
    return sorted(p for p in kernel_dir().glob("*") if p.is_dir() and p.name != "index")


def _damaged() -> dict[str, dict]:
    """The kernel folders whose module or C library is damaged: key → {"path", "reason"}."""
    out = {}
    for folder in _kernel_folders():
        key = folder.name
        found = []
        if _kernel_file(folder, key).exists():
            try:
                found.append((_kernel_file(folder, key), kernel_damage(folder, key)))
            except OSError as e:
                found.append((_kernel_file(folder, key), e.strerror or str(e)))
        found += [(lib, library_damage(lib)) for lib in sorted(folder.glob("native_*.so"))]
        for path, reason in found:
            if reason is not None:
                out[key] = {"path": str(path), "reason": reason}
                break
    return out


def info() -> dict:
    """What the cache holds: its root, size, kernels, index entries and damaged kernels."""
    root = cache_root()
    entries = _entries()
    folders = _kernel_folders()
    damaged = _damaged()
    return {
        "root": str(root),
        "bytes": _size(root) if root.exists() else 0,
        "kernels": [
            {"key": p.name, "bytes": _size(p), **({"damaged": damaged[p.name]} if p.name in damaged else {})}
            for p in folders
        ],
        "entries": [{k: (str(v) if k == "path" else v) for k, v in e.items()} for e in entries],
        "other": {p.name: _size(p) for p in sorted(root.glob("*")) if p.is_dir() and p.name != "kernels"}
        if root.exists()
        else {},
    }


def clear() -> int:
    """Remove the whole cache; returns the bytes freed.  Kernels compile again on next use."""
    import shutil

    root = cache_root()
    if not root.exists():
        return 0
    freed = _size(root)
    shutil.rmtree(root, ignore_errors=True)
    return freed


def prune(current: dict[tuple[str, str], str | None], unused_days: float | None = None) -> dict:
    """Remove what can no longer be used, and return what was removed.

    ``current`` maps (system, variant) of every system known here to its fingerprint now:
    an index entry of a known system with another fingerprint was built from sources that
    have changed since (stale).  Entries of systems not known here are kept, unless unused
    for ``unused_days``.  A damaged kernel (its module fails its checksum, its C library does
    not load) and the entries pointing to it are removed (``damaged`` lists them).  Kernel
    folders that no remaining entry points to are removed."""
    import shutil
    import time

    removed_entries, removed_kernels, freed = [], [], 0
    now = time.time()
    keep_keys = set()
    damaged = _damaged()
    for e in _entries():
        label = (e["system"], e["variant"])
        stale = label in current and current[label] != e["fingerprint"]
        old = unused_days is not None and now - e["last_used"] > unused_days * 86400
        broken = e["key"] is None or e["key"] in damaged
        if stale or old or broken:
            freed += _size(e["path"])
            e["path"].unlink(missing_ok=True)
            removed_entries.append(
                {
                    "system": e["system"],
                    "variant": e["variant"],
                    "reason": "stale" if stale else ("unused" if old else "damaged"),
                }
            )
        else:
            keep_keys.add(e["key"])
    for folder in _kernel_folders():
        if folder.name not in keep_keys:
            freed += _size(folder)
            shutil.rmtree(folder, ignore_errors=True)
            removed_kernels.append(folder.name)
    return {
        "entries": removed_entries,
        "kernels": removed_kernels,
        "damaged": [{"key": k, **v} for k, v in damaged.items()],
        "bytes": freed,
    }
