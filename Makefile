# `make demo` and `make test` each build the virtual environment from nothing (idempotently).
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed-stamp

.PHONY: demo test test-fast lint bench clean mediapipe

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e ".[dev]"
	$(PY) -m ipykernel install --sys-prefix --name python3
	touch $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/jaxhand demo

lint: $(STAMP)
	$(VENV)/bin/ruff check jaxhand tests benchmarks

test: lint
	$(PY) -m pytest -n 2 tests

# The quick loop: everything but the tests marked slow (notebooks, end-to-end runs, clusters).
test-fast: lint
	$(PY) -m pytest -n 2 -m "not slow" tests

bench: $(STAMP)
	for b in benchmarks/*.py; do $(PY) $$b || exit 1; done

# MediaPipe 0.10.21 (the last release that ships its hand model) pins numpy<2 and its own opencv
# and jax: it gets an environment of its own, used by `jaxhand landmarks VIDEO -o FILE --python ...`.
MP_VENV := .venv-mediapipe
mediapipe:
	test -x $(MP_VENV)/bin/python || python3.11 -m venv $(MP_VENV)
	$(MP_VENV)/bin/python -m pip install --quiet "mediapipe==0.10.21" "numpy<2"
	@echo "run: jaxhand landmarks VIDEO -o FILE --python $(MP_VENV)/bin/python"

clean:
	rm -rf $(VENV) .pytest_cache build *.egg-info
