# Two commands on a fresh clone: `make demo` and `make test`. Both create .venv when missing.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-stamp

.PHONY: demo test test-fast install lock sample-logs bench clean browser

# constraints.txt pins every package (and pip) a fresh .venv gets: the same versions on every
# machine and in CI, so byte-exact outputs (sample logs, shown figures) stay reproducible.
$(STAMP): pyproject.toml constraints.txt
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet -c constraints.txt pip
	@# PYTHONWARNINGS: setuptools' build backend prints a boxed 'Editable installation' notice
	@# on every editable install; the user can do nothing about it, so it is not shown
	PYTHONWARNINGS=ignore $(BIN)/python -m pip install --quiet -c constraints.txt -e '.[test]'
	@echo "compiling the SNGP kernels once (numba cache; later runs load them in < 1 s) ..."
	@$(BIN)/python -c "import droneid.sngp as s; print(f'compiled in {s.warmup():.1f} s')"
	@touch $(STAMP)

install: $(STAMP)

# Refresh constraints.txt: the newest releases pyproject.toml admits, resolved in a throw-away
# venv and frozen. Run make test after it (sample logs are byte-exact: regenerate them with
# make sample-logs when a writer's library moved) and commit both.
lock:
	rm -rf .venv-lock && $(PYTHON) -m venv .venv-lock
	.venv-lock/bin/python -m pip install --quiet --upgrade pip
	PYTHONWARNINGS=ignore .venv-lock/bin/python -m pip install --quiet -e '.[test]'
	{ sed -n '1,3p' constraints.txt; .venv-lock/bin/python -m pip --version | awk '{print "pip==" $$2}'; \
	  .venv-lock/bin/python -m pip freeze --exclude-editable; } > constraints.txt.new
	mv constraints.txt.new constraints.txt && rm -rf .venv-lock

demo: $(STAMP)
	$(BIN)/python -m droneid demo

# -n auto: one pytest worker per core (pytest-xdist); the tests are independent processes' work.
# --dist worksteal: an idle worker takes tests queued for the other, so the suite's long real-log
# tests do not leave one core idle at the end (fresh clone, 2 cores: 10:47 with xdist's default
# scheduling, 9:10 with worksteal; docs/benchmarks.md)
PYTEST := $(BIN)/python -m pytest -q -n auto --dist worksteal

test: $(STAMP)
	$(PYTEST)

test-fast: $(STAMP)
	$(PYTEST) -m "not slow"

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
