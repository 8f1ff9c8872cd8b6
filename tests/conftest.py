"""The test run's shared state, set once: one kernel cache for the run (warmed before the first
test, see tests/_warm.py), the registry of systems as it was before each test, and the order and
grouping of tests for xdist (``make test`` runs two workers)."""

import os
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))
os.environ.setdefault("MPLBACKEND", "Agg")

# -------------------------------------------------------------------------------- the kernel cache


def pytest_configure(config):
    # One kernel cache for the run, its xdist workers and every subprocess a test starts (they
    # inherit the environment): $NMKANE_CACHE_DIR as given (.ci/run: a new empty folder), else the
    # default one, named explicitly so that a test changing HOME or XDG_CACHE_HOME does not move it.
    from nmkane_core.kernel.cache import cache_root

    os.environ["NMKANE_CACHE_DIR"] = str(cache_root())


def _warm_wanted(config) -> bool:
    """Warm the shared cache first: in the controller (or a run without xdist) of a whole run —
    with xdist workers or under CI — unless NMKANE_TEST_WARM=0; NMKANE_TEST_WARM=1 forces it.
    A developer's ``pytest tests/x.py`` compiles what it uses, as before."""
    wanted = os.environ.get("NMKANE_TEST_WARM", "")
    if hasattr(config, "workerinput") or config.option.collectonly or wanted == "0":
        return False
    workers = getattr(config.option, "numprocesses", None) or 0
    return wanted == "1" or os.environ.get("CI") == "true" or workers != 0


def pytest_sessionstart(session):
    """Before the first test (and before xdist starts its workers): the shared cache warmed once,
    in two processes, with what nearly every test module compiles otherwise (tests/_warm.py)."""
    if not _warm_wanted(session.config):
        return
    from tests import _warm

    reporter = session.config.pluginmanager.get_plugin("terminalreporter")

    def log(line: str) -> None:
        if reporter is not None:
            reporter.write_line(f"nmkane tests: {line}")

    _warm.warm(Path(os.environ["NMKANE_CACHE_DIR"]), processes=min(2, os.cpu_count() or 1), log=log)


# ------------------------------------------------------------------------- property-based tests
# The property tests (hypothesis; schemathesis builds on it) draw the same examples on every run
# (derandomize, no example database): a suite green on one fresh machine is green on the next, a
# failure repeats, and a run takes the same time.  `make fuzz` (HYPOTHESIS_PROFILE=explore) draws
# new examples each time, to look for what the fixed ones miss.
try:
    from hypothesis import settings as _hypothesis_settings
except ImportError:  # the dev extras are not installed: those tests are not collected either
    pass
else:
    _hypothesis_settings.register_profile("deterministic", derandomize=True, database=None)
    _hypothesis_settings.register_profile("explore", derandomize=False, database=None)
    _hypothesis_settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "deterministic"))


# ---------------------------------------------------------------- where the suite spends
# NMKANE_TEST_CPU=FILE: each test's wall seconds and CPU seconds (setup, call and teardown) appended
# to FILE as "wall<TAB>cpu<TAB>test id": the test's process (its threads included), the children it
# waited for, and what its live descendants (a browser, a server) used meanwhile; what to shorten.
_CPU = os.environ.get("NMKANE_TEST_CPU")


def _cpu_so_far() -> float:
    import resource

    own = resource.getrusage(resource.RUSAGE_SELF)
    waited = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + waited.ru_utime + waited.ru_stime + _live_descendants_cpu()


def _live_descendants_cpu() -> float:
    parent_of, ticks = {}, {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:  # it ended meanwhile
            continue
        pid = int(stat.parent.name)
        parent_of[pid], ticks[pid] = int(fields[1]), int(fields[11]) + int(fields[12])
    mine, total = {os.getpid()}, 0
    for pid in sorted(parent_of):  # parents have lower pids, nearly always: enough for a measurement
        if parent_of[pid] in mine:
            mine.add(pid)
            total += ticks[pid]
    return total / os.sysconf("SC_CLK_TCK")


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    if not _CPU:
        yield
        return
    import time

    wall, cpu = time.perf_counter(), _cpu_so_far()
    yield
    with open(_CPU, "a") as f:
        f.write(f"{time.perf_counter() - wall:.2f}\t{_cpu_so_far() - cpu:.2f}\t{item.nodeid}\n")


# -------------------------------------------------------------------------------- shared state


@pytest.fixture(autouse=True)
def _registry_as_it_was():
    """Systems a test registers (a plugged-in example, a user's system) are unregistered after it:
    the next test sees the registry as it was (the catalogue, the web app's scenes, the service's
    warm-up steps all follow the registry, and a test counting or warming every system would
    otherwise depend on which tests ran before it)."""
    from nmkane_core.run import plugins, registry

    before, loaded = set(registry.system_names()), set(plugins._LOADED)
    yield
    for name in set(registry.system_names()) - before:
        registry.unregister(name)
    for key in set(plugins._LOADED) - loaded:  # a systems file loaded again registers again
        del plugins._LOADED[key]


SESSION_GROUPS = {"quick_runs": "paper", "quick_report": "paper"}  # session fixtures made once, on one worker


# ------------------------------------------------------------------------------- make check

# The modules left out of ``make check`` (a developer's quick loop: ``-m "not slow and not browser
# and not heavy"``), each for what makes it long: a server or a CLI in a subprocess, a system
# compiled of its own, long runs.  ``make test`` runs them all.  A single long test elsewhere
# carries ``@pytest.mark.heavy`` itself.
HEAVY = {
    "tests/backend/test_backend_kill.py": "kills and restarts a service process",
    "tests/backend/test_backend_serve.py": "starts nmkane serve",
    "tests/backend/test_backend_sweep_restart.py": "restarts a service during a sweep",
    "tests/backend/test_backend_schema_fuzz.py": "hundreds of generated requests",
    "tests/backend/test_hardening_serve.py": "starts nmkane serve on an empty cache",
    "tests/backend/test_serve_web_failure.py": "starts nmkane serve",
    "tests/backend/test_slow_readers.py": "a service process measured with 40 clients that read nothing",
    "tests/cli/test_cli.py": "the CLI in subprocesses, the bench",
    "tests/paper/test_figures.py": "draws every figure of the paper",
    "tests/paper/test_paper_claims.py": "the paper's runs",
    "tests/run/test_nonpolynomial_constraints.py": "compiles its own systems",
    "tests/run/test_plugins.py": "compiles plugged-in systems in subprocesses",
    "tests/run/test_catalogue_no_options.py": "runs and exports every catalogue system",
    "tests/run/test_user_system.py": "compiles its own systems",
    "tests/systems/test_closed_loops_compiled.py": "compiles the closed loops",
    "tests/systems/test_iftomm.py": "derives the IFToMM models",
    "tests/systems/test_iftomm_a02_n40.py": "registers and runs the 81-rod chain",
    "tests/systems/test_kanes_method_oracle.py": "sympy's KanesMethod on every system",
    "tests/web/test_classroom.py": "a class of sessions on a served page",
    "tests/web/test_hardening_web.py": "sessions on a served page",
    "tests/kernel/test_codegen.py": "compiles kernels on empty caches",
    "tests/kernel/test_native.py": "compiles kernels with C functions",
    "tests/kernel/test_cache_damage.py": "damages and rebuilds kernels in fresh processes",
    "tests/declare/test_user_system_declaration.py": "compiles its own systems",
    "tests/declare/test_forces_declaration.py": "compiles forces in fresh processes",
    "tests/run/test_point_forces_closed_forms.py": "compiles its own systems",
    "tests/systems/test_whipple_bicycle.py": "the bicycle's benchmark runs",
    "tests/systems/test_bicycle_events_stability.py": "compiles its own systems",
    "tests/systems/test_bicycle_tyre_forces.py": "sympy's KanesMethod on the bicycle",
    "tests/docs/test_pages.py": "runs the pages' examples",
    "tests/sweep/test_sweep.py": "a Dask cluster",
}
# single long tests of modules that are otherwise quick (node id prefixes)
HEAVY_TESTS = (
    "tests/kernel/test_codegen.py::test_the_callees_compiled_beside_a_new_loop_are_those_the_loops_call",
    "tests/web/test_web_catalogue.py::test_a_plugged_in_system_gets_the_generic_page",
    "tests/web/test_web_shapes.py::test_every_kind_is_drawn_where_its_declaration_puts_it",
    "tests/web/test_web_matrices.py::test_the_latex_is_the_simplified_form_and_nothing_is_elided",
    "tests/backend/test_backend_limits.py::test_adaptive_run_stops_at_the_row_cap_with_bounded_memory",
    "tests/run/test_hardening_library.py::test_a_progress_bar_is_drawn_on_a_terminal_that_reports_no_size",
    "tests/run/test_library_fuzz.py::test_appell_hamel_runs_never_report_ok_with_nonfinite_values",
    "tests/integrate/test_singular_switching.py::test_singular_start_with_no_cure_stops_as_singular",
    "tests/test_access.py::test_importing_access_loads_no_web_framework",
    "tests/run/test_simulate_core.py::test_compiled_rhs_agrees_with_numpy_reference_to_1e12",
    "tests/web/test_web_catalogue.py::test_performance_switch_and_slider_to_new_motion",
    "tests/run/test_library_fuzz.py::test_sliding_particle_runs_never_report_ok_with_nonfinite_values",
    "tests/backend/test_backend_api.py::test_singular_and_diverged_runs_are_normal_results",
    "tests/web/test_web_study.py::test_map_equals_direct_simulate_runs_and_a_cell_loads_into_the_sliders",
    "tests/web/test_web_study.py::test_holonomic_gains_and_a_generic_system",
    "tests/web/test_web_guard.py::test_typed_text_over_the_websocket_is_read_exactly_or_refused_beside_the_box",
    "tests/cli/test_plot.py::test_bad_expression_exits_2_naming_the_option_and_the_names",
    "tests/backend/test_backend_limits.py::test_a_running_simulation_does_not_block_the_event_loop",
    "tests/kernel/test_cache_keys.py::test_a_plugged_in_system_copied_to_another_folder_keeps_its_key",
)


def _mark_heavy(items) -> None:
    for item in items:
        if item.nodeid.split("::", 1)[0] in HEAVY or item.nodeid.startswith(HEAVY_TESTS):
            item.add_marker(pytest.mark.heavy)


# -------------------------------------------------------------------------------- xdist


@pytest.hookimpl(tryfirst=True)  # before xdist's own, which reads the groups into the node ids
def pytest_collection_modifyitems(config, items):
    """Under xdist (``--dist loadgroup``): the tests of a module stay on one worker (module-scoped
    fixtures and the user systems a module compiles are made once), so do the modules sharing an
    expensive session fixture (the paper's quick runs), the browser tests share one worker and
    one Chromium, and the groups with slow tests go first, so that the two workers end together.
    Everywhere: the modules of HEAVY marked ``heavy``."""
    _mark_heavy(items)
    if not hasattr(config, "workerinput"):
        return
    modules: dict[str, list] = {}
    for item in items:
        modules.setdefault(item.nodeid.split("::", 1)[0], []).append(item)
    group_of = {}
    for module, its in modules.items():
        shared = {SESSION_GROUPS[f] for i in its for f in i.fixturenames if f in SESSION_GROUPS}
        group_of[module] = shared.pop() if shared else module
    for item in items:
        if item.get_closest_marker("xdist_group") is None:
            module = item.nodeid.split("::", 1)[0]
            item.add_marker(
                pytest.mark.xdist_group("browser" if item.get_closest_marker("browser") else group_of[module])
            )
    first = {_group(i) for i in items if i.get_closest_marker("slow") or i.get_closest_marker("browser")}
    items[:] = sorted(items, key=lambda i: _group(i) not in first)  # a stable sort: file order otherwise


def _group(item) -> str:
    mark = item.get_closest_marker("xdist_group")
    return mark.kwargs.get("name", mark.args[0] if mark.args else "")


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


def pytest_terminal_summary(terminalreporter, config):
    """The order's seed at the end of a shuffled run (make test-shuffled; -q hides the header)."""
    seed = config.getoption("randomly_seed", None) if config.pluginmanager.hasplugin("randomly") else None
    if isinstance(seed, int):
        terminalreporter.write_line(f"test order shuffled: SEED={seed} make test-shuffled repeats it")


@pytest.fixture()
def made(monkeypatch):
    """The texts of the sweep axes whose values were made (``sweep.spec._values`` spied on):
    a sweep too large is refused before any is (issue 44)."""
    from nmkane_core.sweep import spec as spec_module

    calls: list[str] = []
    real = spec_module._values

    def spy(a):
        calls.append(a.text)
        return real(a)

    monkeypatch.setattr(spec_module, "_values", spy)
    return calls
