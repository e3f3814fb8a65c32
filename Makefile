# The two commands of README: `make demo` and `make test`. Each creates .venv and installs
# what it needs, so they work on a fresh machine.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python

.PHONY: demo test lint bench clean

$(VENV)/.base: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --disable-pip-version-check -e .
	touch $@

$(VENV)/.test: $(VENV)/.base
	$(PY) -m pip install --quiet --disable-pip-version-check -e '.[test]'
	touch $@

demo: $(VENV)/.base
	$(VENV)/bin/laser-corners demo --output demo.png

test: $(VENV)/.test
	$(PY) -m ruff check src tests benchmarks
	$(PY) -m pytest -rs

lint: $(VENV)/.test
	$(PY) -m ruff check src tests benchmarks
	$(PY) -m ruff format --check src tests benchmarks

bench: $(VENV)/.base
	$(PY) benchmarks/bench_detector.py

clean:
	rm -rf $(VENV) .pytest_cache build *.egg-info src/*.egg-info
