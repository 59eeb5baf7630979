# tire_estimation: the two set-up commands are `make demo` and `make test`.
SHELL := /bin/bash
.SHELLFLAGS := -eu -o pipefail -c
ROOT := $(abspath $(dir $(lastword $(MAKEFILE_LIST))))
ENV := source $(ROOT)/env.sh
DEMO_OUT ?= $(ROOT)/out/demo

.PHONY: setup demo test lint format bench lock clean

setup:  ## venv with pinned wheels + colcon build (idempotent, seconds when done)
	bash scripts/setup.sh

demo: setup  ## the main job: a demo on a bundled bag
	$(ENV) && bash scripts/demo.sh "$(DEMO_OUT)"

test: setup  ## lint + the whole test suite
	$(ENV) && bash scripts/run_tests.sh

lint: setup
	$(ENV) && ruff check . && ruff format --check .

format: setup
	$(ENV) && ruff format . && ruff check --fix .

bench: setup  ## benchmarks (not part of the tests); results go to docs/results.md by hand
	$(ENV) && python -m tire_estimation.bench

lock:  ## regenerate requirements/lock.txt from requirements/direct.txt in a scratch venv
	bash scripts/lock.sh

clean:
	rm -rf ros2_ws/build ros2_ws/install ros2_ws/log .setup-stamps out
