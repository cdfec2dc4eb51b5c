# Two commands on a fresh clone: `make demo` and `make test`. Both create .venv when missing.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-stamp

.PHONY: demo test test-fast install sample-logs bench clean browser

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

# a headless browser for the screenshot tests (tests/unit/test_screenshot*.py, which skip without
# one); not part of `make test`: a clean clone stays green without it
browser:
	@if command -v chromium >/dev/null 2>&1 || command -v chromium-browser >/dev/null 2>&1; then \
		echo "chromium is installed: $$(command -v chromium || command -v chromium-browser)"; \
	elif command -v apt-get >/dev/null 2>&1 && [ "$$(id -u)" = 0 ]; then \
		apt-get install -y chromium || { apt-get update && apt-get install -y chromium; }; \
	elif command -v apt-get >/dev/null 2>&1 && command -v sudo >/dev/null 2>&1; then \
		sudo apt-get install -y chromium || { sudo apt-get update && sudo apt-get install -y chromium; }; \
	else \
		echo "no apt-get here: install Chromium with your package manager, or set DRONEID_CHROMIUM"; exit 1; \
	fi

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache
