# Two commands from a fresh clone: `make run` and `make test`. Both create .venv/ first.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: run test test-floors bench lint examples example-paradigm psychopy docs clean

# Installed again when the Makefile changes (how it installs may have: 14 s).
# Compiled ahead, on every core: what pinarray, its tests and its UI import. Not the packages'
# own tests, the installers, mypy (`make lint` compiles what it uses as it runs) nor pygments'
# five hundred lexers: half the processor time of compiling everything (20 s here).
NOT_COMPILED := site-packages/.*/tests?/|site-packages/(mypy|mypyc|pip|setuptools|pkg_resources)/|/pygments/lexers/

$(STAMP): pyproject.toml Makefile
	@$(PYTHON) -c 'import sys; sys.exit(0 if sys.version_info >= (3, 11) else "pinarray needs Python 3.11 or newer")'
	@# Without a pip of its own to set up first (6 s here): uv installs pip beside the rest.
	$(PYTHON) -m venv --without-pip $(VENV)
	@# uv (from the package index, into the venv) installs the packages: 14 s from a fresh
	@# clone here, against 23 s for pip. The system's pip puts uv there (pip 22.3 or newer
	@# installs into another environment); an older one, or none, gives the venv a pip of
	@# its own for it. Where uv cannot be had, pip.
	@# The build backend's notes about editable installs are not ours to act on: keep them quiet.
	@# Editable as a path on sys.path (editable_mode=compat), not through an import hook, which
	@# type checkers cannot follow: `make examples` checks a lab's script against pinarray's
	@# own types (tests/typing_canary.py).
	($(PYTHON) -m pip --python $(BIN)/python install --quiet uv 2> /dev/null \
		|| ($(BIN)/python -m ensurepip --default-pip > /dev/null \
			&& $(BIN)/python -m pip install --quiet uv)) \
	&& PYTHONWARNINGS=ignore::UserWarning \
		$(BIN)/uv pip install --quiet --python $(BIN)/python -e '.[dev]' pip \
		--config-settings editable_mode=compat \
	|| (([ -x $(BIN)/pip ] || $(BIN)/python -m ensurepip --default-pip > /dev/null) \
		&& PYTHONWARNINGS=ignore::UserWarning $(BIN)/python -m pip install --quiet --no-compile \
		-e '.[dev]' --config-settings editable_mode=compat)
	$(BIN)/python -m compileall -q -j 0 -x '$(NOT_COMPILED)' pinarray \
		"$$($(BIN)/python -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')"
	touch $(STAMP)

# Quitting with the run unfinished (exit status 4: the UI's last line says how to resume) is
# a normal end of a rehearsal, not an error of make's.
# Bytecode cached, as on any lab PC, even where this environment says not to
# (PYTHONDONTWRITEBYTECODE): the UI would otherwise compile pinarray at every start.
run: $(STAMP)
	@PYTHONDONTWRITEBYTECODE= "$(BIN)/pinarray" tui protocols/localisation.yaml --sim || [ $$? -eq 4 ]

# On every core, twice over: much of the suite waits (pseudo-terminals, the UI's idle waits),
# so more workers than cores keep the processors busy; the real-time tests run beside the
# rest at a higher priority (tests/suite.py). Bytecode is cached even where the environment
# says not to (PYTHONDONTWRITEBYTECODE): every test process would otherwise compile again.
JOBS ?= $(shell $(PYTHON) -c 'import os; print(min(8, 2 * len(os.sched_getaffinity(0))))')

test: $(STAMP)
	PYTHONDONTWRITEBYTECODE= $(BIN)/python -m tests.suite -n $(JOBS)

# The lowest versions pyproject.toml allows (.ci/floors.txt), in a second environment: the
# numeric, protocol, analysis and bus tests (the UI's snapshots are drawn by today's Textual).
FLOOR_VENV := .venv-floors
FLOOR_TESTS := tests/softness tests/analysis tests/adaptive tests/hardware tests/test_schedule.py tests/test_plan.py \
	tests/test_protocol_load.py tests/test_bad_input.py tests/test_observer.py tests/test_grid.py \
	tests/test_compile_outputs.py tests/test_cues.py tests/test_calibration_file.py \
	tests/test_packaging.py

# Installed by the main environment's uv (9 s here, against 73 s for pip); pip where uv fails.
FLOOR_PACKAGES := --constraint .ci/floors.txt -e . pytest hypothesis pytest-asyncio pytest-xdist \
	pytest-rerunfailures feetech-servo-sdk
$(FLOOR_VENV)/.installed: $(STAMP) pyproject.toml .ci/floors.txt
	$(PYTHON) -m venv --without-pip $(FLOOR_VENV)
	PYTHONWARNINGS=ignore::UserWarning $(BIN)/uv pip install --quiet \
		--python $(FLOOR_VENV)/bin/python $(FLOOR_PACKAGES) \
	|| ($(FLOOR_VENV)/bin/python -m ensurepip --default-pip > /dev/null \
		&& PYTHONWARNINGS=ignore::UserWarning $(FLOOR_VENV)/bin/python -m pip install --quiet \
		$(FLOOR_PACKAGES))
	touch $@

# In the two lanes of `make test` (tests/suite.py): the bus tests behind pseudo-terminals are
# real-time ones, which fail now and then among four workers on a busy machine.
test-floors: $(FLOOR_VENV)/.installed
	PYTHONDONTWRITEBYTECODE= $(FLOOR_VENV)/bin/python -m tests.suite -n $(JOBS) -p no:cacheprovider \
		-W ignore::DeprecationWarning -W ignore::PendingDeprecationWarning \
		$(FLOOR_TESTS)

# psignifit 4 (GPL-3.0) is the thresholds benchmark's reference (bench_thresholds): installed
# here, for the benchmarks alone, so that neither pinarray nor `make test`'s setup needs it.
BENCH_STAMP := $(VENV)/.bench-installed
$(BENCH_STAMP): $(STAMP)
	$(BIN)/python -m pip install --quiet 'psignifit==4.3'
	touch $@

# Timed as a lab's machine runs pinarray: with its bytecode cached (see run).
bench: $(BENCH_STAMP)
	PYTHONDONTWRITEBYTECODE= $(BIN)/python -m tests.benchmarks

lint: $(STAMP)
	$(BIN)/ruff check pinarray tests examples
	$(BIN)/mypy pinarray
	$(BIN)/lint-imports --no-cache

# The example experiment as a lab runs it: the script against the simulated array, its own
# tests through pinarray's pytest fixture (the plugin pytest finds by entry point), and the
# strictest type check a lab might run on it (from inside examples/, pinarray is seen as an
# installed package, as a lab's checker sees it), with a deliberate type error beside it that
# must be caught: a check that saw pinarray as Any would pass anything (tests/typing_canary.py).
examples: $(STAMP)
	results=$$(mktemp -d) && $(BIN)/python examples/which_pin.py --subject ci --seed 1 \
		--results $$results && rm -rf $$results
	log=$$(mktemp) && $(BIN)/python examples/stimuli_in_code.py --log $$log && rm -f $$log
	cd examples && ../$(BIN)/python -m pytest -q -p no:cacheprovider --ignore=tap_count .
	$(BIN)/python -m tests.typing_canary

# A lab's own paradigm as its own package (examples/tap_count/, docs/programmers/paradigms.md):
# installed beside pinarray in an environment of its own (so that `make test` never sees it),
# found by its entry point, and its own tests run there: validate, batch, analyse, read back.
PARADIGM_VENV := .venv-paradigm
$(PARADIGM_VENV)/.installed: $(STAMP) pyproject.toml examples/tap_count/pyproject.toml
	$(PYTHON) -m venv $(PARADIGM_VENV)
	PYTHONWARNINGS=ignore::UserWarning $(BIN)/uv pip install --quiet \
		--python $(PARADIGM_VENV)/bin/python -e . -e examples/tap_count pytest mypy \
	|| (PYTHONWARNINGS=ignore::UserWarning $(PARADIGM_VENV)/bin/python -m pip install --quiet \
		-e . -e examples/tap_count pytest mypy)
	touch $@

example-paradigm: $(PARADIGM_VENV)/.installed
	cd examples/tap_count && ../../$(PARADIGM_VENV)/bin/python -m pytest -q -p no:cacheprovider
	@# The package strictly typed against pinarray's own types, read from the checkout.
	cd examples/tap_count && MYPYPATH=../.. ../../$(PARADIGM_VENV)/bin/mypy --strict \
		--no-incremental --follow-imports=silent pinarray_tap_count

# The PsychoPy plugin (pinarray/psychopy/), for real: PsychoPy's library (`psychopy-lib`) and
# pinarray[psychopy] in an environment of their own, a virtual display (Xvfb, installed from
# Debian's packages when missing) started by the job itself, and tests/psychopy/: the entry
# points PsychoPy loads, the device its DeviceManager finds, waves armed on flips, the example
# experiment, the Builder component (the example .psyexp compiled as Builder compiles it, and
# its script run). `make test` never imports PsychoPy. Nothing compiled ahead: only what runs is.
PSYCHOPY_VENV := .venv-psychopy
# Installed by the main environment's uv (21 s here, against 97 s for pip); pip where uv fails.
$(PSYCHOPY_VENV)/.installed: $(STAMP) pyproject.toml
	$(PYTHON) -m venv --without-pip $(PSYCHOPY_VENV)
	PYTHONWARNINGS=ignore::UserWarning $(BIN)/uv pip install --quiet \
		--python $(PSYCHOPY_VENV)/bin/python -e '.[psychopy]' pytest pytest-xdist pytest-rerunfailures \
	|| ($(PSYCHOPY_VENV)/bin/python -m ensurepip --default-pip > /dev/null \
		&& PYTHONWARNINGS=ignore::UserWarning $(PSYCHOPY_VENV)/bin/python -m pip install \
		--quiet --no-compile -e '.[psychopy]' pytest pytest-xdist pytest-rerunfailures)
	touch $@

psychopy: $(PSYCHOPY_VENV)/.installed
	@command -v Xvfb > /dev/null || { apt-get update -qq && apt-get install -y -qq xvfb > /dev/null; }
	@# Two test processes: much of it waits on frames and real-time trials (176 -> 120-137 s).
	@# Real-time tests all: one that fails is tried once more, and the report says why it
	@# failed first (tests/reruns.py; a player starved past its answer's margin while CI ran
	@# make test-floors, lint and docs beside, 1 run in 3 on 2026-11-28).
	$(PYTHON) tests/psychopy/xvfb.py $(PSYCHOPY_VENV)/bin/python -m pytest \
		-c tests/psychopy/pytest.ini -n 2 --reruns 1 -rR -p tests.reruns tests/psychopy

# The documentation site (docs/, mkdocs.yml) built strictly: a broken link, a reference that
# does not resolve or a public name without a docstring fails it. Its tools are an extra of
# their own, so `make test` does not install them.
DOCS_STAMP := $(VENV)/.docs-installed
$(DOCS_STAMP): $(STAMP)
	PYTHONWARNINGS=ignore::UserWarning $(BIN)/uv pip install --quiet --python $(BIN)/python \
		-e '.[docs]' --config-settings editable_mode=compat \
	|| PYTHONWARNINGS=ignore::UserWarning $(BIN)/python -m pip install --quiet --no-compile \
		-e '.[docs]' --config-settings editable_mode=compat
	touch $@

docs: $(DOCS_STAMP)
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict --site-dir site

clean:
	rm -rf $(VENV) $(FLOOR_VENV) $(PSYCHOPY_VENV) $(PARADIGM_VENV) build site *.egg-info
