# nmkane — `make serve` starts the app, `make test` runs every test. Both set up .venv first.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: setup serve test bench figures clean

$(STAMP): pyproject.toml
	@$(PY) -c 'import sys; sys.exit(0 if sys.version_info >= (3, 11) else "nmkane needs Python >= 3.11 (set PY=python3.11)")'
	$(PY) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q -e '.[test]'
	@touch $(STAMP)

setup: $(STAMP)

serve: setup
	$(BIN)/nmkane serve

test: setup
	$(BIN)/python -m pytest -q

bench: setup
	$(BIN)/nmkane bench

figures: setup
	$(BIN)/nmkane figures --out figures

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache
