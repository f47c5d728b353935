# Two commands on a fresh machine: `make demo` (the main job on shipped defaults) and `make test`.
# Both build or reuse the virtual environment in .venv (`make setup`).
SHELL := /bin/bash
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
PACKAGES := ros_ws/src/robot_bridge ros_ws/src/flex_ident ros_ws/src/rod_deploy

# DDS stays on this machine: loopback discovery, a random domain, logs in a temp dir.
export ROS_AUTOMATIC_DISCOVERY_RANGE := LOCALHOST
export ROS_DOMAIN_ID ?= $(shell echo $$(( RANDOM % 100 + 1 )))
export ROS_LOG_DIR ?= $(shell mktemp -d /tmp/ros_log.XXXXXX)
export MPLBACKEND := Agg

.PHONY: setup test demo colcon clean bench-env

setup: $(STAMP)

$(STAMP): requirements.txt $(addsuffix /setup.py,$(PACKAGES))
	test -x $(PY) || python3 -m venv $(VENV)
	$(PY) -m pip install --disable-pip-version-check -q -r requirements.txt
	$(PY) -m pip install --disable-pip-version-check -q --no-deps --no-build-isolation $(addprefix -e ,$(PACKAGES))
	bash scripts/compile_kernels.sh
	touch $(STAMP)

test: setup
	$(PY) -m pytest

demo: setup
	$(PY) scripts/demo.py

# colcon build of the three packages (executables in ros_ws/install/<pkg>/lib/<pkg>/, ament index registered)
colcon: setup
	cd ros_ws && ../$(VENV)/bin/colcon build --symlink-install

# benchmark-only environment for the independent simulator (PyElastica, benchmarks/pyelastica_replay.py);
# rod_deploy is importable from the work tree through PYTHONPATH (see the script's docstring), not installed here.
BENCH_VENV := .venv-bench
BENCH_STAMP := $(BENCH_VENV)/.installed

bench-env: $(BENCH_STAMP)

$(BENCH_STAMP):
	test -x $(BENCH_VENV)/bin/python || python3 -m venv $(BENCH_VENV)
	$(BENCH_VENV)/bin/python -m pip install --disable-pip-version-check -q pyelastica==1.0.0 numpy scipy pyyaml matplotlib
	touch $(BENCH_STAMP)

clean:
	rm -rf ros_ws/build ros_ws/install ros_ws/log .pytest_cache
