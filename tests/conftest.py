import os
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))
os.environ.setdefault("MPLBACKEND", "Agg")


@pytest.fixture(scope="session")
def quick_runs():
    """The runs of ``nmkane figures --quick``, made once for every test that checks a claim or the report."""
    from nmkane_core.paper import collect_runs

    return collect_runs(quick=True, progress=False)


@pytest.fixture(scope="session")
def quick_report(quick_runs, tmp_path_factory):
    """The report of ``nmkane figures --quick`` (figures and report files), drawn from :func:`quick_runs`."""
    from nmkane_core.paper import make_figures

    return make_figures(str(tmp_path_factory.mktemp("figures")), progress=False, runs=quick_runs)
