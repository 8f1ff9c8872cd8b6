# nmkane — `make serve` starts the app, `make test` runs every test. Both set up .venv first.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
# packages are installed by uv (from PyPI, into the venv): the versions pip resolves, a fresh .venv
# with the dev extras in 31-42 s where pip took 66-82 s (2 cores, empty caches); with their
# bytecode, as pip writes it: where PYTHONDONTWRITEBYTECODE=1 is set (as on the machine these
# numbers come from), nothing writes it later and every process would compile what it imports
# again (the tests' warm-up took 259 s instead of 171). Where uv cannot be had or fails (a machine
# that reaches only pip's own index), pip installs them
install = ($(BIN)/python -m pip install -q uv >/dev/null 2>&1 && $(BIN)/uv pip install -q --compile-bytecode --python $(BIN)/python $(1)) \
	|| $(BIN)/python -m pip install -q $(1)

.PHONY: setup setup-dev serve test test-shuffled fuzz check lint format docs docs-serve bench figures clean

# the app (library, REST service, web app, figures); the dev stamp adds tests and linters; then the
# compiled core is built once with the machine's C compiler (about a second; without one: a
# one-line error saying what to install)
$(VENV)/.installed-all: pyproject.toml
	@$(PY) -c 'import sys; sys.exit(0 if sys.version_info >= (3, 11) else "nmkane needs Python >= 3.11 (set PY=python3.11)")'
	$(PY) -m venv $(VENV)
	@echo "nmkane: installing the packages into $(VENV) (about half a minute on a fresh machine)"
	$(call install,-e '.[all]')
	$(BIN)/python -m nmkane_core.kernel.core
	@touch $@

$(VENV)/.installed-dev: $(VENV)/.installed-all
	@echo "nmkane: installing the test, lint and docs tools into $(VENV)"
	$(call install,-e '.[dev]')
	@touch $@

setup: $(VENV)/.installed-all
setup-dev: $(VENV)/.installed-dev

serve: setup
	$(BIN)/nmkane serve

# two xdist workers (CI has two cores); tests/conftest.py warms the shared kernel cache once first and
# groups tests (a module, a session fixture, the browser tests) onto one worker each: --dist loadgroup;
# the 30 slowest tests are listed at the end (what to shorten next)
# in file order (-p no:randomly); make test-shuffled runs the same suite in a random order, to
# find tests that pass only after others (it prints the seed: SEED=N make test-shuffled repeats it)
TEST_WORKERS ?= 2
test: setup-dev
	$(BIN)/python -m pytest -q -n $(TEST_WORKERS) --dist loadgroup --durations=30 -p no:randomly

SEED ?=
test-shuffled: setup-dev
	$(BIN)/python -m pytest -q -n $(TEST_WORKERS) --dist loadgroup --durations=30 $(if $(SEED),--randomly-seed=$(SEED))

# the property tests (hypothesis, schemathesis) with new random examples: make test draws the same
# ones on every run (tests/conftest.py), so that a green suite stays green; this looks further
FUZZ_TESTS := tests/run/test_library_fuzz.py tests/symbolic/test_nonminimal_structure.py tests/backend/test_backend_schema_fuzz.py
fuzz: setup-dev
	HYPOTHESIS_PROFILE=explore $(BIN)/python -m pytest -q -p no:randomly $(FUZZ_TESTS)

# a developer's quick loop: lint, then the tests that need no server, subprocess, browser or
# system compiled of its own (markers: tests/conftest.py HEAVY); make test stays the whole suite
check: lint
	$(BIN)/python -m pytest -q -n $(TEST_WORKERS) --dist loadgroup -m "not slow and not browser and not heavy" -p no:randomly

lint: setup-dev
	$(BIN)/ruff check nmkane_core backend web tests scripts examples
	$(BIN)/ruff format --check nmkane_core backend web tests scripts examples
	$(BIN)/mypy
	$(BIN)/lint-imports

format: setup-dev
	$(BIN)/ruff check --fix nmkane_core backend web tests scripts examples
	$(BIN)/ruff format nmkane_core backend web tests scripts examples

# the docs site (mkdocs, strict: a broken link, a missing reference or a docstring that does
# not render fails the build) into site/; docs-serve rebuilds it on change at 127.0.0.1:8001
DOCS_ENV := NO_MKDOCS_2_WARNING=1 DISABLE_MKDOCS_2_WARNING=true PYTHONPATH=$(CURDIR)

docs: setup-dev
	$(DOCS_ENV) $(BIN)/mkdocs build --strict --site-dir site

docs-serve: setup-dev
	$(DOCS_ENV) $(BIN)/mkdocs serve --strict --dev-addr 127.0.0.1:8001

bench: setup
	$(BIN)/nmkane bench

figures: setup
	$(BIN)/nmkane figures --out figures

clean:
	rm -rf $(VENV) build site *.egg-info .pytest_cache .mypy_cache .ruff_cache
