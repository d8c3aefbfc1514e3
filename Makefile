# The two commands of the README, and a few more. Each target bootstraps first (idempotent).
SHELL := /bin/bash
ENV := source tools/env.sh
PYTEST_ARGS ?=

.PHONY: bootstrap demo test lint reproduce clean

bootstrap:
	@tools/bootstrap.sh

demo: bootstrap
	@$(ENV) && tools/demo.sh

test: bootstrap
	@$(ENV) && ROS_PYTHON_CHECK_FIELDS=1 python -m pytest $(PYTEST_ARGS)

reproduce: bootstrap
	@$(ENV) && python -m amb_apps.reproduce --out out/reproduce

lint: bootstrap
	@$(ENV) && ruff check . && ruff format --check .

clean:
	rm -rf build install log
