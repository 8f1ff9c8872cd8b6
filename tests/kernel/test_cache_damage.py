"""A damaged kernel cache entry (a truncated module, a garbage C library) is found, rebuilt with
one line that names it, and counted by ``nmkane cache prune`` (issue 44, item 8).

Each case runs in fresh processes on a temporary cache (``NMKANE_CACHE_DIR``), with the smallest
system, the sliding particle."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from tests._helpers import require_compiler

RUN = """
from nmkane_core import simulate
run = simulate({"system": "sliding-particle", "t_final": 0.2, "dt": 0.01}, progress=False)
print(run.summary["status"])
"""


def _env(cache: Path) -> dict[str, str]:
    return {**os.environ, "NMKANE_CACHE_DIR": str(cache)}


def _simulate(cache: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", RUN], env=_env(cache), capture_output=True, text=True, timeout=600)


def _cached(cache: Path) -> Path:
    """The cache's only kernel folder after a first run."""
    done = _simulate(cache)
    assert done.returncode == 0, done.stderr
    (folder,) = [p for p in (cache / "kernels").iterdir() if p.name != "index"]
    return folder


def _truncate(path: Path) -> None:
    text = path.read_bytes()
    path.write_bytes(text[: len(text) // 2])


def _one_notice(stderr: str, path: Path) -> None:
    lines = [line for line in stderr.splitlines() if line.strip()]
    assert "Traceback" not in stderr
    assert lines == [f"nmkane: kernel cache entry {path} was damaged ({lines[0].split('(', 1)[1]}"]
    assert lines[0].endswith("); rebuilt")


def test_a_truncated_cached_description_is_rebuilt_with_one_line_naming_it(tmp_path):
    folder = _cached(tmp_path)
    module = next(folder.glob("nmkane_kernel_*.json"))
    _truncate(module)
    done = _simulate(tmp_path)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["ok"]
    _one_notice(done.stderr, module)
    again = _simulate(tmp_path)  # rebuilt whole: the next process says nothing
    assert again.returncode == 0 and again.stderr == "", again.stderr


def _garbage_is_rebuilt(cache: Path, library: Path) -> None:
    """``library`` overwritten with garbage: the next run is ok, says so in one line, rebuilds it."""
    library.write_bytes(os.urandom(4096))
    done = _simulate(cache)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["ok"]
    _one_notice(done.stderr, library)
    assert library.read_bytes()[:4] == b"\x7fELF"


def test_a_garbage_c_library_is_rebuilt_with_one_line_naming_it(tmp_path):
    require_compiler()
    (library,) = _cached(tmp_path).glob("native_*.so")
    _garbage_is_rebuilt(tmp_path, library)


def test_a_garbage_compiled_core_is_rebuilt_with_one_line_naming_it(tmp_path):
    require_compiler()
    _cached(tmp_path)
    (library,) = (tmp_path / "core").glob("nmkcore_*.so")
    _garbage_is_rebuilt(tmp_path, library)


def test_cache_prune_counts_and_removes_a_damaged_kernel(tmp_path):
    folder = _cached(tmp_path)
    module = next(folder.glob("nmkane_kernel_*.json"))
    _truncate(module)
    cli = [sys.executable, "-m", "nmkane_core.cli", "cache"]
    info = subprocess.run([*cli, "info"], env=_env(tmp_path), capture_output=True, text=True, timeout=120)
    assert info.returncode == 0, info.stderr
    assert f"damaged  {module}" in info.stdout
    done = subprocess.run([*cli, "prune"], env=_env(tmp_path), capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert f"removed damaged {module}" in done.stdout
    assert "(1 damaged)" in done.stdout
    assert "removed sliding-particle / nonminimal (damaged)" in done.stdout
    assert not folder.exists()
    assert list((tmp_path / "kernels" / "index").glob("*.json")) == []


def test_cache_prune_removes_compiled_builds_of_older_sources(tmp_path):
    """An update leaves the core's and the models' specialised builds of the old sources in the
    cache (keyed by their sources, never loaded again): ``nmkane cache prune`` removes those and
    keeps the current ones."""
    folder = _cached(tmp_path)
    (current,) = (tmp_path / "core").glob("nmkcore_*.so")
    old_core = tmp_path / "core" / "nmkcore_000000000000000000000000.so"
    old_special = folder / "special_000000000000000000000000.so"
    for path in (old_core, old_special):
        path.write_bytes(b"an older build")
    cli = [sys.executable, "-m", "nmkane_core.cli", "cache", "prune"]
    done = subprocess.run(cli, env=_env(tmp_path), capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert "and 2 compiled builds of older sources" in done.stdout, done.stdout
    assert current.exists() and not old_core.exists() and not old_special.exists()
