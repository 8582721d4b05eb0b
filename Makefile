# snakebot: `make demo` and `make test` are the quick start; each does the set-up it needs.

PYTHON      ?= python3
VENV        := .venv
PY          := $(VENV)/bin/python
PIP         := $(PY) -m pip
APT_PACKAGES := gcc-arm-none-eabi libnewlib-arm-none-eabi qemu-system-arm clang libclang-rt-14-dev
CORE_FILES  := $(wildcard firmware/core/*.c firmware/core/*.h)
PORT        ?=

.PHONY: help setup system-packages python-env core firmware test lint bench demo flash clean fuzz docs

help:
	@echo "make demo      run the main job on the emulated robot (does its own set-up)"
	@echo "make test      run the whole test suite (does its own set-up)"
	@echo "make setup     install system packages, create .venv, install snakebot"
	@echo "make firmware  cross-compile the firmware (arm-none-eabi-gcc)"
	@echo "make bench     run the benchmarks"
	@echo "make fuzz FUZZ_SECONDS=60   fuzz the parser and the PC link (libFuzzer, clang)"
	@echo "make lint      ruff"
	@echo "make docs      API reference from the docstrings (pdoc) into build/docs/"
	@echo "make flash PORT=/dev/ttyUSB0   flash the CM-530 through the ROBOTIS bootloader"

setup: system-packages python-env

# Installs only what is missing, so a prepared machine is not touched (and needs no root).
system-packages:
	@missing=""; for p in $(APT_PACKAGES); do \
	  dpkg-query -W -f='$${Status}' $$p 2>/dev/null | grep -q "install ok installed" || missing="$$missing $$p"; \
	done; \
	if [ -n "$$missing" ]; then \
	  echo "installing system packages:$$missing"; \
	  SUDO=$$( [ "$$(id -u)" = 0 ] || echo sudo ); \
	  $$SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq $$missing >/dev/null; \
	fi

python-env: $(VENV)/.installed $(VENV)/.core

$(VENV)/.installed: pyproject.toml setup.py
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PIP) install -q --upgrade pip setuptools wheel cffi
	$(PIP) install -q --no-build-isolation -e '.[dev]'
	touch $@

# Rebuilds snakebot._core when the C core changes.
$(VENV)/.core: $(VENV)/.installed $(CORE_FILES) host/snakebot/_core_build.py
	$(PIP) install -q --no-build-isolation --no-deps -e .
	touch $@

core: $(VENV)/.core

firmware: system-packages
	$(MAKE) -C firmware

test: setup firmware
	$(PY) -m ruff check .
	$(PY) -m pytest

# Each fuzz target runs FUZZ_SECONDS (fuzz/Makefile: regress, minimize, seeds).
FUZZ_SECONDS ?= 60
fuzz: system-packages
	$(MAKE) -C fuzz run FUZZ_SECONDS=$(FUZZ_SECONDS) PYTHON=$(PYTHON)

lint: python-env
	$(PY) -m ruff check .
	$(PY) -m ruff format --check . || true

bench: setup firmware
	@for b in bench/bench_*.py; do echo "== $$b"; $(PY) $$b || exit 1; done

demo: setup firmware
	$(PY) -m snakebot demo

flash: setup firmware
	@test -n "$(PORT)" || { echo "error: give the controller's port: make flash PORT=/dev/ttyUSB0"; exit 2; }
	$(PY) -m snakebot flash build/cm530/firmware.bin --port $(PORT)

# API reference from the docstrings; the prose documents are docs/*.md.
DOCS_DIR ?= build/docs
docs: python-env
	$(PY) -m pdoc --docformat restructuredtext -o $(DOCS_DIR) snakebot '!snakebot\._'

clean:
	rm -rf build $(VENV) host/*.egg-info
	find . -name __pycache__ -prune -exec rm -rf {} +
