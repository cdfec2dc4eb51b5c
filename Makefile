# Two commands on a fresh clone: `make demo` and `make test`. Both create .venv when missing.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-stamp

.PHONY: demo test test-fast install sample-logs bench clean

$(STAMP): pyproject.toml
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	@# PYTHONWARNINGS: setuptools' build backend prints a boxed 'Editable installation' notice
	@# on every editable install; the user can do nothing about it, so it is not shown
	PYTHONWARNINGS=ignore $(BIN)/python -m pip install --quiet -e '.[test]'
	@echo "compiling the SNGP kernels once (numba cache; later runs load them in < 1 s) ..."
	@$(BIN)/python -c "import droneid.sngp as s; print(f'compiled in {s.warmup():.1f} s')"
	@touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	$(BIN)/python -m droneid demo

# -n auto: one pytest worker per core (pytest-xdist); the tests are independent processes' work
test: $(STAMP)
	$(BIN)/python -m pytest -q -n auto

test-fast: $(STAMP)
	$(BIN)/python -m pytest -q -n auto -m "not slow"

sample-logs: $(STAMP)
	$(BIN)/python -m droneid sample-logs --out sample_logs

bench: $(STAMP)
	$(BIN)/python benchmarks/run_all.py

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache
