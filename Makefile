# activesurv: `make demo` and `make test` set everything up themselves (see README).
SHELL := /bin/bash
.DEFAULT_GOAL := help
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
PIP := $(PY) -m pip --disable-pip-version-check
STAMPS := $(VENV)/.stamps
# A marker inherited from another venv's Python would stop ours from setting LD_LIBRARY_PATH.
unexport _ROS_WHEELS_BOOTSTRAP_COMPLETE

PKGS := activesurv_common activesurv_launch activesurv_recording activesurv_liveview \
        activesurv_hardware activesurv_evaluation activesurv_studies activesurv_sim activesurv_imaging activesurv_prediction \
        activesurv_dispatch activesurv_fusion activesurv_stages activesurv_bringup
IFACE_SRC := $(wildcard src/activesurv_interfaces/msg/*.msg) \
             src/activesurv_interfaces/CMakeLists.txt src/activesurv_interfaces/package.xml \
             src/activesurv_interfaces/pyproject.toml scripts/build_interfaces.sh \
             $(wildcard src/vendor/tf2_msgs/msg/*.msg src/vendor/tf2_msgs/srv/*.srv) \
             src/vendor/tf2_msgs/CMakeLists.txt src/vendor/tf2_msgs/package.xml
PKG_META := $(foreach p,$(PKGS),src/$(p)/setup.py src/$(p)/setup.cfg src/$(p)/package.xml src/$(p)/pyproject.toml) \
            $(wildcard src/*/config/*.yaml)
CORE_DIRS := $(foreach p,$(PKGS),src/$(p)/$(p))
TEST_ARGS ?=
# Two pytest-xdist workers: the graph tier in one (a run at a time, as a lab machine would run
# them), everything else in the other (conftest.py's groups); TEST_JOBS=0 runs in one process.
TEST_JOBS ?= 2

.PHONY: help setup demo test bench lint lock clean

help:
	@echo 'make demo   - set up and run the main job (the paper experiments)'
	@echo 'make test   - set up and run the whole test suite'
	@echo 'make bench  - benchmarks, written to bench/results.json'
	@echo 'make lint   - ruff + mypy --strict on the core modules'
	@echo 'make setup  - only create/refresh .venv (idempotent; every target calls it)'

# Two jobs: the kernels compile (numba) while the interfaces build (CMake); the two share the
# cores here (150 -> 145 s), a machine with more saves up to the kernels' 25 s.
setup:
	@$(MAKE) --no-print-directory -j2 $(STAMPS)/bytecode

$(STAMPS)/venv:
	$(PYTHON) -m venv $(VENV)
	@mkdir -p $(STAMPS) && touch $@

# The wheels come through uv (pinned in constraints.txt): it downloads and unpacks them in
# parallel and byte-compiles them on every core (a fresh set-up: 48 s against pip's 82 s on one
# host). Where uv cannot reach the wheels (a mirror known only to pip's configuration), pip
# installs them instead.
UV := $(VENV)/bin/uv
$(STAMPS)/deps: $(STAMPS)/venv requirements.txt constraints.txt
	$(PIP) install -q -c constraints.txt uv
	$(UV) pip install -q --python $(PY) --compile-bytecode -r requirements.txt -c constraints.txt \
	  || { echo 'uv could not install the wheels: pip installs them (slower)'; \
	       $(PIP) install -q -r requirements.txt -c constraints.txt; }
	@touch $@

$(STAMPS)/interfaces: $(STAMPS)/deps $(IFACE_SRC)
	VENV=$(abspath $(VENV)) scripts/build_interfaces.sh
	@touch $@

# Beside the interfaces' build (it needs only the wheels): the editable installs take the core
# the kernels leave when they are done.
$(STAMPS)/packages: $(STAMPS)/deps $(PKG_META)
	$(UV) pip install -q --python $(PY) --no-deps --no-build-isolation $(foreach p,$(PKGS),-e src/$(p)) \
	  || $(PIP) install -q --no-deps --no-build-isolation $(foreach p,$(PKGS),-e src/$(p))
	@touch $@

# The imager's and the renderer's compiled loops (numba), cached beside their source: compiled
# here once, not by the first camera of the first run. They import only numpy and numba, so
# they compile from the source tree beside the interfaces' build (numba's cache is keyed on
# the file, the same one the installed packages load).
KERNELS := src/activesurv_imaging/activesurv_imaging/kernels.py \
	src/activesurv_sim/activesurv_sim/render_kernels.py
$(STAMPS)/kernels: $(STAMPS)/deps $(KERNELS)
	@echo 'compiling the imaging and rendering kernels (once, about 25 s)'
	PYTHONPATH=$(CURDIR)/src/activesurv_imaging $(PY) -c 'from activesurv_imaging.kernels import warm_up; warm_up()'
	PYTHONPATH=$(CURDIR)/src/activesurv_sim $(PY) -c 'from activesurv_sim.render_kernels import warm_up; warm_up()'
	@touch $@

# Our modules byte-compiled, and again whenever one changes (under a second): where
# PYTHONDONTWRITEBYTECODE is set (this machine, its CI) Python keeps nothing it compiles, and
# every process of a run compiled every module of ours from source at its start.
SOURCES := $(shell find $(CORE_DIRS) -name '*.py')
$(STAMPS)/bytecode: $(STAMPS)/kernels $(STAMPS)/interfaces $(STAMPS)/packages $(SOURCES)
	$(PY) -m compileall -q $(CORE_DIRS) > /dev/null
	@touch $@

demo: setup
	$(VENV)/bin/activesurv demo

test: setup
	$(PY) -m pytest -n $(TEST_JOBS) --dist loadgroup --no-loadscope-reorder $(TEST_ARGS)

bench: setup
	$(PY) bench/run.py --out bench/results.json

lint: setup
	$(VENV)/bin/ruff check src test bench conftest.py
	$(VENV)/bin/ruff format --check src test bench conftest.py
	$(VENV)/bin/mypy --strict $(CORE_DIRS)

lock: setup
	$(PIP) freeze --exclude-editable | grep -v '^activesurv' > constraints.txt.new
	@echo 'wrote constraints.txt.new: review, then move it over constraints.txt'

clean:
	rm -rf $(VENV) build install log .pytest_cache .mypy_cache .ruff_cache
