# Every target that runs code first creates/refreshes the local virtual environment,
# installed exactly from uv.lock (nothing is resolved at install time).
# Update the lock after changing a dependency: `make lock` (see the README).
PY ?= python3
UV_VERSION := 0.13.9
UV_DIR := .uv
UV := $(UV_DIR)/bin/uv
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
# uv uses this interpreter and never downloads one; the environment lives in .venv.
UV_ENV := UV_PROJECT_ENVIRONMENT=$(VENV) UV_PYTHON_DOWNLOADS=never UV_PYTHON=$(PY)
PROFILE ?=
# Bytecode is written where a module is first imported, whatever the machine says
# (PYTHONDONTWRITEBYTECODE is set on CI machines and some containers): pytest rewrites the
# asserts of every test module and of its plugins' modules (hypothesis: about 140) in each
# process, each xdist worker, and can only keep the result as bytecode. Without it every
# pytest process compiled them again: collection of the suite took 20 s instead of 11 s.
unexport PYTHONDONTWRITEBYTECODE

.PHONY: run test test-unit test-runtime test-realtime test-all test-slow test-newest lint bench clean venv lock

# uv itself, pinned, in its own small environment (pip from PyPI).
$(UV):
	$(PY) -m venv $(UV_DIR)
	$(UV_DIR)/bin/python -m pip install -q uv==$(UV_VERSION)

# Bytecode is compiled at install: where PYTHONDONTWRITEBYTECODE is set (CI machines, some
# containers) nothing is ever cached, and every process (the motion process, the emulated
# servos, each CLI run) would compile its imports again: about 7.6 s instead of 2.7 s for
# the motion process. The project's own modules are compiled too; an edited one is simply
# compiled again in memory (its stale bytecode is never used).
$(STAMP): pyproject.toml uv.lock | $(UV)
	$(UV_ENV) $(UV) sync --frozen --extra dev --quiet --compile-bytecode
	$(BIN)/python -m compileall -q spm_console benchmarks >/dev/null
	touch $(STAMP)

lock: $(UV)
	$(UV_ENV) $(UV) lock

venv: $(STAMP)

run: $(STAMP)
	$(BIN)/spm-console tui $(if $(PROFILE),--profile $(PROFILE)) $(if $(GRID),--grid-step $(GRID))

# The unit tests (no process, no terminal: tests/unit) on every core, then the rest on three
# workers, each test module a group: their motions run in simulated time (tests/conftest.py
# sets SPM_CONSOLE_CLOCK=simulated), so nothing waits on the wall clock, and a third worker
# fills the time the other two spend waiting on their processes and on the console's idle
# checks (two workers kept the two cores 54 % busy). The unit tests are not run beside the
# rest: docs/decisions/test-suite-time.md says what that did. The tests about real time
# (marked realtime) are left to test-realtime.
test: test-unit test-runtime

test-unit: $(STAMP)
	SPM_TESTS_HOST_STALLS=0 $(BIN)/python -m pytest tests/unit -m 'not slow and not realtime' -n auto

test-runtime: $(STAMP)
	$(BIN)/python -m pytest tests/runtime tests/tui tests/e2e -m 'not slow and not realtime' \
		-n 3 --dist loadgroup --durations=25

# The tests about real time (marked realtime: jitter, scheduling, reply timing, runs on the
# wall clock), one at a time with nothing beside them.
test-realtime: $(STAMP)
	$(BIN)/python -m pytest tests -m 'realtime and not slow' --durations=15

test-all: $(STAMP)
	$(BIN)/python -m pytest -m ''

test-slow: $(STAMP)
	$(BIN)/python -m pytest -m slow

# The newest releases pyproject.toml allows, resolved from the package registry (not the lock)
# into a throw-away environment, against the --json contract and the core's unit tests: a new
# release that prints on stdout or changes an API we use fails here first. README: "Newest
# dependencies".
NEWEST := .venv-newest
test-newest: $(UV)
	rm -rf $(NEWEST)
	UV_PYTHON_DOWNLOADS=never $(UV) venv --quiet --python $(PY) $(NEWEST)
	VIRTUAL_ENV=$(NEWEST) UV_PYTHON_DOWNLOADS=never $(UV) pip install --quiet --compile-bytecode \
		--resolution highest -e ".[dev]"
	VIRTUAL_ENV=$(NEWEST) $(UV) pip freeze > $(NEWEST)/versions.txt
	grep -iE '^(numpy|scipy|cvxpy|osqp|clarabel|daqp|highspy|control|textual|pydantic|mujoco)==' $(NEWEST)/versions.txt
	SPM_TESTS_HOST_STALLS=0 $(NEWEST)/bin/python -m pytest -m '' -p no:cacheprovider -n 2 \
		tests/e2e/test_json_contract.py tests/e2e/test_json_stdout.py tests/unit/core tests/unit/cli

lint: $(STAMP)
	$(BIN)/ruff check spm_console tests benchmarks
	$(BIN)/mypy
	$(BIN)/lint-imports

bench: $(STAMP)
	$(BIN)/python -m benchmarks

clean:
	rm -rf $(VENV) $(NEWEST) $(UV_DIR) .cache .mypy_cache .ruff_cache .pytest_cache
