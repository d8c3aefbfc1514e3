# The two commands of the README, and a few more. Each target bootstraps first (idempotent).
SHELL := /bin/bash
ENV := source tools/env.sh
PYTEST_ARGS ?=

SECTIONS ?=

.PHONY: bootstrap demo test lint reproduce results clean

bootstrap:
	@tools/bootstrap.sh

demo: bootstrap
	@$(ENV) && tools/demo.sh

test: bootstrap
	@$(ENV) && ROS_PYTHON_CHECK_FIELDS=1 python -m pytest $(PYTEST_ARGS)

reproduce: bootstrap
	@$(ENV) && python -m amb_apps.reproduce --out out/reproduce

# docs/results.md from the project's own commands; SECTIONS="modal prediction" for some only
# (tools/results.py --list names them and their cost).
results: bootstrap
	@$(ENV) && python tools/results.py $(SECTIONS)

lint: bootstrap
	@$(ENV) && ruff check . && ruff format --check .

clean:
	rm -rf build install log
