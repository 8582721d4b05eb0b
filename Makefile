# snakebot: `make demo` and `make test` are the quick start; each does the set-up it needs.
# Quiet by default: V=1 shows every command, here and in firmware/ and fuzz/.

PYTHON      ?= python3
VENV        := .venv
PY          := $(VENV)/bin/python
PIP         := $(PY) -m pip
CORE_FILES  := $(wildcard firmware/core/*.c firmware/core/*.h)
PORT        ?=
V           ?= 0
Q           := $(if $(filter 1,$(V)),,@)
PIP_QUIET   := $(if $(filter 1,$(V)),,-q)
export V

# The demo needs the C compiler and headers for snakebot._core and the ARM cross-compiler
# (its board, the emulated CM-530, runs in Python); the tests add QEMU (the second,
# independent emulator of the firmware: `--board qemu`), clang (libFuzzer and the
# sanitizers), zlib (the PC-link fuzz target's CRC-32) and tmux (the `snakebot drive`
# terminal test).
# MuJoCo's offscreen renderer (--video) draws through EGL, or OSMesa where EGL is missing,
# both on Mesa's software rasteriser: no display and no GPU needed. The tests add Xvfb
# (`sim view`, MuJoCo's viewer on a virtual display).
DEMO_APT    := gcc python3-dev python3-venv gcc-arm-none-eabi libnewlib-arm-none-eabi \
               libegl1 libegl-mesa0 libgl1-mesa-dri libosmesa6
TEST_APT    := $(DEMO_APT) qemu-system-arm clang libclang-rt-14-dev zlib1g-dev tmux xvfb
export MUJOCO_GL ?= egl
# Python caches compiled modules (and pytest its rewritten test modules) in __pycache__:
# without the cache every test process and every `python -m snakebot` a test starts
# compiles the package again (an environment that sets PYTHONDONTWRITEBYTECODE made
# each collection of the suite cost 16 s of CPU instead of 7).
unexport PYTHONDONTWRITEBYTECODE

# pytest workers for the stages of `make test` (see there): twice the cores for most of
# the suite, one per core for the tests that run QEMU, one for the `late` tests (two
# ended that lane sooner, but their load beside the serial stage made its emulated
# controllers miss replies in fresh clones' CI runs), one more than the cores for the
# serial tests (they mostly wait on ptys and the wall clock: with the fault campaigns in
# a lane of their own beside them, on 2 cores 3 workers took 102 s where 2 took 148 s;
# 4 at nice -10 with the campaigns among them kept QEMU's campaigns from their pace, a
# PING unanswered in 2 of 5 runs).
TEST_JOBS   ?= $(shell echo $$(( $$(nproc) * 2 )))
QEMU_JOBS   ?= $(shell nproc)
SERIAL_JOBS ?= $(shell echo $$(( $$(nproc) + 1 )))
LATE_JOBS   ?= 1

.PHONY: dist help setup system-packages demo-packages python-env runtime-env core firmware \
        test test-summary test-collect test-parallel test-late test-qemu test-serial test-campaigns test-fuzz test-wheel lint fuzz-targets bench demo flash flash-image clean fuzz docs

help:
	@echo "make demo      run the main job on the emulated robot (does its own set-up)"
	@echo "make test      run the whole test suite (does its own set-up)"
	@echo "make setup     install system packages, create .venv, install snakebot with its dev extras"
	@echo "make firmware  cross-compile the firmware (arm-none-eabi-gcc)"
	@echo "make bench     run the benchmarks"
	@echo "make fuzz FUZZ_SECONDS=60   fuzz the parser and the PC link (libFuzzer, clang)"
	@echo "make lint      ruff check, ruff format --check, and the Python 3.10 check (vermin)"
	@echo "make dist      the sdist and the wheel into dist/ (python -m build)"
	@echo "make docs      API reference from the docstrings (pdoc) into build/docs/"
	@echo "make flash PORT=/dev/ttyUSB0   flash the CM-530 through the ROBOTIS bootloader"
	@echo "V=1 shows the commands (compiler lines included)"

setup: system-packages python-env

# Installs only what is missing, so a prepared machine is not touched (and needs no root).
define apt_install
	@missing=""; for p in $(1); do \
	  dpkg-query -W -f='$${Status}' $$p 2>/dev/null | grep -q "install ok installed" || missing="$$missing $$p"; \
	done; \
	if [ -n "$$missing" ]; then \
	  echo "installing system packages:$$missing"; \
	  SUDO=$$( [ "$$(id -u)" = 0 ] || echo sudo ); \
	  $$SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq $$missing >/dev/null; \
	fi
endef

system-packages:
	$(call apt_install,$(TEST_APT))

demo-packages:
	$(call apt_install,$(DEMO_APT))

# .venv in two layers: the runtime with what the demo uses (the `physics` extra for its
# MuJoCo world, `plot` for its picture, `mcu` for its board, the emulated CM-530), then the
# dev extras (tests, lint, benchmarks).
runtime-env: $(VENV)/.runtime $(CORE_LIB)
python-env: $(VENV)/.dev $(CORE_LIB)

$(VENV)/.venv:
	$(Q)test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(Q)$(PIP) install $(PIP_QUIET) --upgrade pip setuptools wheel cffi
	$(Q)touch $@

$(VENV)/.runtime: pyproject.toml setup.py | $(VENV)/.venv
	$(Q)$(PIP) install $(PIP_QUIET) --no-build-isolation -e '.[physics,plot,mcu]'
	$(Q)touch $@

$(VENV)/.dev: $(VENV)/.runtime
	$(Q)$(PIP) install $(PIP_QUIET) --no-build-isolation -e '.[dev]'
	$(Q)touch $@

# Rebuilds snakebot._core when the C core changes, or when the library itself is gone (the
# target is the library, not a stamp beside it).
CORE_LIB := host/snakebot/_core.abi3.so
$(CORE_LIB): $(VENV)/.runtime $(CORE_FILES) host/snakebot/_core_build.py
	$(Q)$(PIP) install $(PIP_QUIET) --no-build-isolation --no-deps -e .
	$(Q)touch $@

core: $(CORE_LIB)

firmware: demo-packages
	$(Q)$(MAKE) --no-print-directory -C firmware

# The static checks, the firmware and the fuzz targets side by side (so no two processes
# compile the same files at once); then, laid out by what was measured on this project's
# 2-core virtual machine, where both busy cores lose time to the host, three lanes at once:
# - the tests that neither run QEMU nor are marked `serial`, on TEST_JOBS workers handed
#   tests as they free up (--dist worksteal), as they wait on ptys and timeouts as much
#   as they compute;
# - the two fuzzing passes one after the other, at a low priority (nice 10) on the cycles
#   the tests leave (a pass lasts its fixed wall time whatever its priority, and still
#   gets a share of the CPU beside busy processes; in the idle scheduling class it got
#   none and timed out);
# - the tests that run the firmware in QEMU, on QEMU_JOBS workers, a test file whole in
#   each (--dist loadfile), which keeps each QEMU pacing its links in real time, in the
#   real-time class (FIRST, below); where that is not allowed, after the other two lanes.
# Then those marked `serial` (real-time pty runs, the transport under faults,
# dynamixel-sdk's fixed waits) on SERIAL_JOBS workers: beside the other stages, even in
# the real-time class, the kernel's own tty work and the third-party clients came late
# (5 of 92 failed). Beside them run the fault campaigns, one at a time in a process of
# their own (test-campaigns: their counts need the emulated board to keep pace, and a
# QEMU campaign lost a PING with another board's campaign running beside it), the
# package check (it builds the wheel, then runs the demo from it in QEMU; test-wheel)
# and the late lane (test-late).
# Every stage but the first writes a log, shown whole if it fails and as one line if not,
# so that outputs do not mix; the first stage prints its progress.
# A stage that fails does not stop the others: each records its result in TEST_STATUS,
# every stage runs, and `make test` ends with the table of results, failing if any did.
FUZZ_TESTS  := tests/reliability/test_fuzz_targets.py
WHEEL_TESTS := tests/packaging/test_wheel.py
CAMPAIGN_TESTS := tests/reliability/test_reliability_campaigns.py
LOW         := nice -n 10
# The QEMU and serial stages emulate hardware in real time, and what they check (the
# firmware's reply windows, its 100 ms PC-link gap, a servo's return delay) is timing:
# they run at a higher priority where that is allowed (root, as in CI).
# - HIGH, nice -10: about nine times a default process's share of the CPU. Enough on an
#   idle machine; beside two busy processes the campaigns still missed PINGs and the
#   demo lost the controller.
# - FIRST, the kernel's round-robin real-time class (chrt --rr 1), where allowed, else
#   HIGH: no process outside it delays an emulated reply (the kernel still keeps 5 % of
#   each second for them), so the QEMU stage runs beside the other stages (REALTIME),
#   and on a busy machine both stages run there. Within the class a process that wants
#   the CPU waits for another's 100 ms turn to end: more busy workers than cores there
#   broke the serial stage's timing, whose workers stay at HIGH on an idle
#   machine, after every other stage.
REALTIME    := $(shell chrt --rr 1 true 2>/dev/null && echo yes)
HIGH        := $(shell nice -n -10 true 2>/dev/null && echo nice -n -10)
FIRST       := $(if $(REALTIME),chrt --rr 1,$(HIGH))
TEST_STATUS := build/test-status
# Other work using this many cores or more when `make test` starts (tests/support/
# busy_cores.py, over one second) makes it a busy machine: there the QEMU and serial
# stages run one test at a time (measured beside two busy processes: with two at once,
# each emulated robot's Python side, a core's worth of work at real time, fell behind,
# its QEMU stopped answering, and the demo lost the controller).
BUSY        := build/test-busy
BUSY_CORES  := 0.5
TEST_STAGES := checks parallel late qemu serial campaigns fuzz wheel
# $(call record,STAGE,STATUS): note STAGE's exit status and pass it on.
record = s=$(2); mkdir -p $(TEST_STATUS); echo $$s > $(TEST_STATUS)/$(1); exit $$s
# $(call logged,STAGE,LABEL), after a command that wrote build/test-STAGE.log: that log
# whole if the command failed, else LABEL and the log's last line; then record its status.
logged = s=$$?; if [ $$s = 0 ]; then echo "$(2): $$(tail -n1 build/test-$(1).log)"; \
  else cat build/test-$(1).log; fi; $(call record,$(1),$$s)
test: system-packages python-env
	@rm -rf $(TEST_STATUS) $(BUSY); mkdir -p build
	@busy=$$($(PY) tests/support/busy_cores.py); \
	  if awk "BEGIN { exit !($$busy >= $(BUSY_CORES)) }"; then touch $(BUSY); \
	  echo "make test: other work keeps $$busy cores busy: the QEMU and serial stages run one test at a time"; fi
	-$(Q)$(MAKE) --no-print-directory -k -j$(TEST_JOBS) lint firmware fuzz-targets test-collect; \
	    $(call record,checks,$$?)
ifdef REALTIME
	-$(Q)$(MAKE) --no-print-directory -k -j3 test-parallel test-fuzz test-qemu
else
	-$(Q)$(MAKE) --no-print-directory -k -j2 test-parallel test-fuzz
	-$(Q)$(MAKE) --no-print-directory test-qemu
endif
	-$(Q)if test -e $(BUSY); then $(MAKE) --no-print-directory test-wheel; \
	  $(MAKE) --no-print-directory -k -j2 test-serial test-late; \
	  $(MAKE) --no-print-directory test-campaigns; \
	  else $(MAKE) --no-print-directory -k -j4 test-serial test-campaigns test-wheel test-late; fi
	$(Q)$(MAKE) --no-print-directory test-summary

test-summary:
	@echo "make test:"; failed=0; for s in $(TEST_STAGES); do \
	  r=$$(cat $(TEST_STATUS)/$$s 2>/dev/null || echo "not run"); \
	  case $$r in 0) w=passed;; "not run") w="NOT RUN"; failed=1;; *) w="FAILED (exit $$r)"; failed=1;; esac; \
	  printf "  %-9s %s\n" $$s "$$w"; done; exit $$failed

# Collecting the suite once beside the builds fills __pycache__ with the rewritten test
# modules, which every pytest worker of the stages after it then reads instead of
# rewriting them itself (a collection error shows in the stage that meets it).
# It also writes which test files each stage runs (tests/conftest.py, MAKE_TEST_STAGE_FILES),
# so that a stage's workers import only those: the QEMU and serial stages need 39 of the
# suite's 200 files, and importing them all cost each worker 7 s of CPU.
STAGE_FILES := build/stages
test-collect:
	-$(Q)rm -rf $(STAGE_FILES); MAKE_TEST_STAGE_FILES=$(STAGE_FILES) \
	    $(PY) -m pytest --collect-only -q -p no:cacheprovider > /dev/null 2>&1
# $(call stage_files,STAGE,LEFT OUT): STAGE's test files, but those in LEFT OUT (run by lanes
# of their own); all of tests/ if the collection did not write them.
stage_files = $$( (cat $(STAGE_FILES)/stage-$(1) 2>/dev/null || echo tests) | \
  grep -v -x -F $(foreach f,$(2),-e $(f)))

test-parallel:
	$(Q)$(PY) -m pytest -n $(TEST_JOBS) --dist worksteal -m "not serial and not qemu and not late" \
	    --ignore=$(FUZZ_TESTS) $(call stage_files,parallel,$(FUZZ_TESTS)); $(call record,parallel,$$?)

# The tests marked `late` (long, CPU-bound, not timing-sensitive: the API reference's
# build, the symbolic fields, the planner's closed loops and programs; the serial stage
# leaves a quarter of the CPU idle) run beside it and the package check at a low
# priority, on the CPU those leave (the serial tests wait on the wall clock): at the
# default priority the emulated bootloader of a serial test once missed its deadline. On
# a busy machine at the default one: the serial stage is in the real-time class there,
# and at nice 10 beside two busy processes the lane got 11 s of CPU in 6 minutes.
test-late:
	@mkdir -p build
	$(Q)prio=$$(test -e $(BUSY) || echo "$(LOW)"); \
	  $$prio $(PY) -m pytest -q -p no:cacheprovider -n $(LATE_JOBS) -m "late and not serial and not qemu" \
	    --ignore=$(FUZZ_TESTS) $(call stage_files,late,$(FUZZ_TESTS)) > build/test-late.log 2>&1; \
	    $(call logged,late,late tests)

test-qemu test-serial: test-%:
	@mkdir -p build
	$(Q)if test -e $(BUSY); then jobs=1; prio="$(FIRST)"; \
	  else jobs=$(STAGE_JOBS_$*); prio="$(STAGE_PRIO_$*)"; fi; \
	  $$prio $(PY) -m pytest -q -p no:cacheprovider -n $$jobs --dist $(STAGE_DIST_$*) \
	    -m "$(STAGE_MARK_$*)" $(addprefix --ignore=,$(LANES)) $(call stage_files,$*,$(LANES)) \
	    > build/test-$*.log 2>&1; $(call logged,$*,$* tests)
STAGE_JOBS_qemu    = $(QEMU_JOBS)
STAGE_PRIO_qemu    = $(FIRST)
STAGE_PRIO_serial  = $(HIGH)
STAGE_MARK_qemu   := qemu and not serial
STAGE_DIST_qemu   := loadfile
STAGE_JOBS_serial  = $(SERIAL_JOBS)
STAGE_MARK_serial := serial
STAGE_DIST_serial := load
# the files that lanes of their own run, left out of the QEMU and serial stages
LANES := $(WHEEL_TESTS) $(CAMPAIGN_TESTS)

# The fault campaigns, one after another (not pytest-xdist's `loadgroup`, which stopped
# grouping with pytest 9.2: pytest-xdist issue #1386).
test-campaigns:
	@mkdir -p build
	$(Q)prio=$$(test -e $(BUSY) && echo "$(FIRST)" || echo "$(HIGH)"); \
	  $$prio $(PY) -m pytest -q -p no:cacheprovider $(CAMPAIGN_TESTS) > build/test-campaigns.log 2>&1; \
	    $(call logged,campaigns,fault campaigns)

# `make test` fuzzes each target TEST_FUZZ_SECONDS, a smoke pass within its 5-minute
# budget; `make fuzz` is the longer pass (FUZZ_SECONDS, below).
TEST_FUZZ_SECONDS ?= 10
test-fuzz:
	@mkdir -p build
	$(Q)FUZZ_SECONDS=$(TEST_FUZZ_SECONDS) FUZZ_LAUNCH="$(LOW)" $(LOW) $(PY) -m pytest -q -p no:cacheprovider $(FUZZ_TESTS) \
	    > build/test-fuzz.log 2>&1; $(call logged,fuzz,fuzz tests)

# The package check runs after the QEMU stage. On an idle machine it runs beside the serial
# stage, whose tests wait on the wall clock and leave half the CPU idle (make test 292 s
# with the check beside the parallel stage, 242..270 s in five runs beside the serial one,
# the serial stage as long either way). On a busy machine it runs alone before the serial
# stage, at its priority: beside the other lanes and two busy processes its demo's QEMU, at
# the default priority, fell so far behind that the demo lost the controller.
test-wheel:
	@mkdir -p build
	$(Q)prio=$$(test -e $(BUSY) && echo "$(FIRST)"); \
	  $$prio $(PY) -m pytest -q -p no:cacheprovider $(WHEEL_TESTS) > build/test-wheel.log 2>&1; \
	    $(call logged,wheel,package check)

fuzz-targets:
	$(Q)$(MAKE) --no-print-directory -C fuzz all

# Each fuzz target runs FUZZ_SECONDS (fuzz/Makefile: regress, minimize, seeds).
FUZZ_SECONDS ?= 60
fuzz: system-packages
	$(Q)$(MAKE) --no-print-directory -C fuzz run FUZZ_SECONDS=$(FUZZ_SECONDS) PYTHON=$(PYTHON)

# Python 3.10 is the oldest supported (Ubuntu 22.04): vermin checks the code needs no more.
lint: python-env
	$(Q)$(PY) -m ruff check .
	$(Q)$(PY) -m ruff format --check .
	$(Q)$(VENV)/bin/vermin --quiet --no-tips --violations --eval-annotations -t=3.10- \
	    host tests bench fuzz protocol setup.py

bench: system-packages python-env firmware
	@for b in bench/bench_*.py; do echo "== $$b"; $(PY) $$b || exit 1; done

demo: demo-packages runtime-env firmware
	$(Q)$(PY) -m snakebot demo

# The port is checked before anything is built or installed.
flash:
	@test -n "$(PORT)" || { echo "error: give the controller's port: make flash PORT=/dev/ttyUSB0"; exit 2; }
	$(Q)$(MAKE) --no-print-directory flash-image

flash-image: demo-packages runtime-env firmware
	$(Q)$(PY) -m snakebot flash build/cm530/firmware.bin --port $(PORT)

# The sdist and the wheel. PyPA's build comes with the dev extras; it must be installed:
# without it `python -m build` finds this checkout's build/ folder (the firmware images)
# and stops with "'build' is a package".
dist: python-env
	$(Q)$(PY) -m build --outdir dist .

# API reference from the docstrings; the prose documents are docs/*.md. Without pdoc's
# "View Source" panes: highlighting the source of every member was half its time, and the
# source is in the repository.
DOCS_DIR ?= build/docs
docs: python-env
	$(PY) -m pdoc --no-show-source --docformat restructuredtext -o $(DOCS_DIR) snakebot '!snakebot\._'

clean:
	rm -rf build dist $(VENV) host/*.egg-info
	find . -name __pycache__ -prune -exec rm -rf {} +
