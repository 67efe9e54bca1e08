# sik_ros: the two README commands (`make run`, `make test`) and their set-up.
# VENV=/path/to/venv selects another venv (default: .venv in the repo); PYTHON=python3.11.

SHELL := /bin/bash
VENV ?= $(CURDIR)/.venv
PYTHON ?= python3.11
PY := $(VENV)/bin/python
# Neither variable is required (rclpy finds its libraries by itself in the venv): Fast DDS is the
# only RMW the wheels ship, and AMENT_PREFIX_PATH lets ament_index_python find the packages in the
# venv (as scripts/env.sh does). ROS_DOMAIN_ID is left to the tests (one per run).
RUN_ENV := RMW_IMPLEMENTATION=rmw_fastrtps_cpp AMENT_PREFIX_PATH=$(VENV)
PYTEST_ARGS ?=

export VENV PYTHON

.PHONY: setup run test test-fast lint bench docs-tables paper clean distclean help

help:
	@echo "make setup   create $(VENV), install the pinned requirements, build sik_interfaces"
	@echo "make run     the demo: sik_node on the bundled Panda model answering IK requests"
	@echo "make test    the test suite (pytest)"
	@echo "make test-fast  unit tests only (no node, nothing slow)"
	@echo "make lint    flake8 and pydocstyle only"
	@echo "make bench   every benchmark (about an hour), then the tables of docs/benchmarks.md"
	@echo "make docs-tables  the tables of docs/benchmarks.md and README.md from docs/results/"
	@echo "make paper   docs/results.md: the paper's experiments on the bundled models and baselines"
	@echo "make clean   remove build products and caches (keeps the venv)"
	@echo "make distclean  also remove the venv"

setup:
	@bash scripts/setup.sh

run: setup
	$(RUN_ENV) $(PY) -m sik_ros.ros.demo

test: setup
	$(RUN_ENV) $(PY) -m pytest -q $(PYTEST_ARGS) test

test-fast: setup
	$(RUN_ENV) $(PY) -m pytest -q -m "not e2e and not slow" $(PYTEST_ARGS) test

lint: setup
	$(PY) -m pytest -q test/test_lint.py

bench: setup
	$(RUN_ENV) PY=$(PY) bash bench/run_all.sh

docs-tables:
	$(PY) bench/render.py

# the bundled SIK models against the shipped baselines (sik_ros/bundles/panda/baselines); the
# latent-size study joins when its models are there (scripts/latent_study.sh: runs/latent)
PAPER_BASELINES ?= sik_ros/bundles/panda/baselines
paper: setup
	$(RUN_ENV) $(PY) -m sik_ros.cli.eval --out docs --baselines $(PAPER_BASELINES) \
	  $(if $(wildcard runs/latent/latent_*.pt),--latent-study runs/latent) --quiet

clean:
	rm -rf build install log $(VENV)/.sik-build *.egg-info .pytest_cache
	find . -path ./.venv -prune -o -name __pycache__ -type d -prune -exec rm -rf {} +

distclean: clean
	rm -rf $(VENV)
