# sirl_jax: the two commands a newcomer needs are `make train TASK=...` and `make test`.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
TASK   ?= hurdle
ARGS   ?=
PYTEST_ARGS ?=
# The ONNX converter of `export`, without its deps (pyproject.toml, extra `export`, says why).
JAX2ONNX := jax2onnx==0.17.1

.PHONY: install test test-slow lint bench train clean

install: $(STAMP)

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	$(PY) -m pip install --quiet --no-deps $(JAX2ONNX)
	touch $(STAMP)

test: $(STAMP)
	JAX_PLATFORMS=cpu $(PY) -m pytest $(PYTEST_ARGS)

test-slow: $(STAMP)
	JAX_PLATFORMS=cpu $(PY) -m pytest -m slow $(PYTEST_ARGS)

lint: $(STAMP)
	$(PY) -m ruff check sirl_jax tests experiments

bench: $(STAMP)
	$(PY) -m experiments.bench.run_all $(ARGS)

train: $(STAMP)
	$(PY) -m sirl_jax train --task $(TASK) $(ARGS)

clean:
	rm -rf $(VENV) .pytest_cache .ruff_cache
