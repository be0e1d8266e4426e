# tiago_nav: one-command set-up, demo, tests and benchmarks on Debian 11, 12 and 13 (see README.md).
# Every target that needs it runs `setup` first; `setup` is idempotent and quick when done.
SHELL := /bin/bash
.SHELLFLAGS := -eo pipefail -c
ROOT := $(CURDIR)
SYS_PY := /usr/bin/python3
VENV := $(ROOT)/.venv
WS := $(ROOT)/.ws
SUDO := $(shell [ "$$(id -u)" = 0 ] || echo sudo)
# Debian's ROS 1 packages (ros_comm 1.15) and what the package uses besides.
APT_PACKAGES := ros-core-dev catkin python3-catkin-pkg python3-rospy python3-actionlib \
	python3-actionlib-msgs python3-tf2-ros python3-tf2-msgs \
	python3-move-base-msgs ros-move-base-msgs libmove-base-msgs-dev python3-nav-msgs \
	python3-sensor-msgs python3-geometry-msgs python3-std-msgs python3-std-srvs \
	python3-diagnostic-msgs \
	python3-visualization-msgs python3-rosgraph-msgs python3-rostest python3-roslaunch \
	python3-dynamic-reconfigure libdynamic-reconfigure-config-init-mutex-dev \
	python3-rosnode python3-rostopic python3-rosservice python3-rosgraph rosbash python3-rosbag \
	ros-robot-state-publisher \
	python3-numpy python3-scipy python3-yaml python3-matplotlib python3-pytest python3-venv \
	cmake g++ catkin-lint
# By Debian release (11 bullseye, 12 bookworm, 13 trixie): Debian 13's Python 3.13 has no pybullet
# wheel, so pip builds it, with Debian's numpy (see venv) and so with setuptools.
DEBIAN_CODENAME := $(shell . /etc/os-release 2>/dev/null && echo "$$VERSION_CODENAME")
APT_PACKAGES_trixie := python3-dev python3-setuptools
APT_PACKAGES += $(APT_PACKAGES_$(DEBIAN_CODENAME))
# PyPI-only packages, in the virtualenv (which sees the system's packages).
# pybullet 3.2.7 on Debian 11, 12 and 13: its cp39 and cp311 wheels import with Debian's numpy
# (1.19, 1.24; it is the cp38 wheel that needs numpy >= 1.23's C API, see README's Noetic line),
# and on 13 pip builds it (see venv).
# dask[distributed]: the batch evaluator's engine (tiago_nav_tools.evaluate only; nothing else imports it),
# pinned by the system's Python (so evaluated after `apt`): 2026.8.0 needs Python >= 3.10, and
# 2024.8.0 is the last release for Debian 11's 3.9.
# vermin: `make lint`'s check that the code needs no Python newer than Noetic's 3.8.
DASK_VERSION = $(shell $(SYS_PY) -c 'import sys; print("2026.8.0" if sys.version_info >= (3, 10) else "2024.8.0")')
PIP_PACKAGES = pybullet==3.2.7 dask[distributed]==$(DASK_VERSION) distributed==$(DASK_VERSION) vermin==1.9.2
# What the workspace build depends on (file(GLOB) lists are re-read when these change).
# (cfg/*.cfg read their tables from the library files CMakeLists.txt lists in TIAGO_NAV_CFG_TABLES)
WS_INPUTS := CMakeLists.txt package.xml setup.py $(wildcard msg/* srv/* action/* cfg/* nodes/* scripts/evaluate test/*.test env-hooks/*) \
	src/tiago_nav/params.py src/tiago_nav/nav/navigator.py src/tiago_nav/nav/controller.py \
	src/tiago_nav/corridor/law.py
ROS_ENV := source $(WS)/devel/setup.bash
# tysik/obstacle_detector for the detection benchmark's comparison (`make obstacle-detector`)
OD_WS := $(ROOT)/.od_ws
# ROS's move_base for the people suite's navigation candidate (`make move-base`)
MB_WS := $(ROOT)/.mb_ws
# `make bench BENCH=detection` runs one benchmark (names: src/tiago_nav_tools/benchmarks.py)
BENCH ?= all
SUITE ?= suites/smoke.yaml
EVAL_OUT ?= eval-results
# ROS masters and nodes started from here bind to loopback only, unless the user chose otherwise
# (docs/evaluation.md: opting in to the network).
ROS_HOSTNAME ?= localhost
ROS_IP ?= 127.0.0.1
export ROS_HOSTNAME ROS_IP

.PHONY: setup apt venv ws demo test unit rostest test-platforms bench obstacle-detector move-base docs evaluate lint \
	clean print-apt-packages print-pip-packages
.DEFAULT_GOAL := setup

setup: apt venv ws

apt:
	@missing=$$({ dpkg-query -W -f='$${Package} $${Status}\n' $(APT_PACKAGES) 2>/dev/null || true; } \
	  | awk '$$NF == "installed" {print $$1}' | sort | comm -13 - <(tr ' ' '\n' <<< "$(APT_PACKAGES)" | sed '/^$$/d' | sort)); \
	if [ -n "$$missing" ]; then \
	  echo "[setup] apt-get install:" $$missing; \
	  $(SUDO) apt-get update -qq; \
	  DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -qq --no-install-recommends $$missing >/dev/null; \
	fi

# The package lists as this platform resolves them (PIP_PACKAGES asks the Python that `apt` installs).
print-apt-packages:
	@echo $(APT_PACKAGES)
print-pip-packages:
	@echo $(PIP_PACKAGES)

# apt first (order-only: the system's Python, numpy and python3-venv), also under make -j
venv: $(VENV)/.done
$(VENV)/.done: Makefile | apt
	@[ -x $(VENV)/bin/python ] || { echo "[setup] virtualenv $(VENV)"; $(SYS_PY) -m venv --system-site-packages $(VENV); }
	@echo "[setup] pip install $(PIP_PACKAGES)"
	@# without the shell's PYTHONPATH: a sourced workspace (another clone's) can put its own
	@# virtualenv's pybullet there, and pip then installs nothing into this one.
	@# --no-build-isolation: where pip must build pybullet (no wheel, e.g. Python 3.13) it then
	@# builds against the system's numpy, which its setup.py looks for; in pip's isolated build
	@# environment it finds none and builds pybullet without numpy, whose batch ray test then reads
	@# the simulator's ray arrays element by element.
	@# CFLAGS: pybullet.c's numpy code passes a PyObject* as a PyArrayObject*, an error from GCC 14
	@# on (Debian 13), a warning before (no effect where pip installs a wheel).
	@PYTHONPATH= CFLAGS="$${CFLAGS:-} -Wno-error=incompatible-pointer-types" \
	  $(VENV)/bin/python -m pip install -q --disable-pip-version-check --no-build-isolation \
	  $(foreach p,$(PIP_PACKAGES),'$(p)')
	@touch $@

# .ws/src/tiago_nav is a folder of links to the repository's entries (not one link to the
# repository, whose .ws/ inside would make a loop that rosrun's `find -L` walks into).
ws: $(WS)/.done
$(WS)/.done: $(WS_INPUTS) $(VENV)/.done
	@mkdir -p $(WS)/src/tiago_nav
	@find $(WS)/src/tiago_nav -maxdepth 1 -type l -delete
	@for f in $(ROOT)/* $(ROOT)/.ci; do \
	  case "$$(basename $$f)" in .ws|.venv|.git) ;; *) ln -sfn "$$f" $(WS)/src/tiago_nav/ ;; esac; done
	@echo "[setup] catkin_make in $(WS)"
	@cd $(WS) && catkin_make --force-cmake -DPYTHON_EXECUTABLE=$(SYS_PY) \
	  -DTIAGO_NAV_VENV=$(VENV) -DCATKIN_ENABLE_TESTING=ON > $(WS)/build.log 2>&1 \
	  || { tail -40 $(WS)/build.log; echo "[setup] catkin_make failed, see $(WS)/build.log"; exit 1; }
	@touch $@

# DEMO_ARGS: scripts/run_demo.py's options, e.g. "--rtf 0 --png out/mission.png" (--help lists them)
demo: setup
	@$(ROS_ENV) && $(SYS_PY) $(ROOT)/scripts/run_demo.py $(DEMO_ARGS)

test: setup
	@$(ROS_ENV) && $(SYS_PY) $(ROOT)/test/run_all.py

unit: setup
	@$(ROS_ENV) && $(SYS_PY) $(ROOT)/test/run_all.py --unit-only

rostest: setup
	@$(ROS_ENV) && $(SYS_PY) $(ROOT)/test/run_all.py --rostest-only

# The other platform rows (docs/getting-started.md#platforms), each set up from the registries
# in its own cached environment under .platforms/ (TIAGO_NAV_PLATFORMS) and tested there; needs
# no `setup` on this machine. Rows: noetic-python, debian11, debian12, debian13.
PLATFORMS ?= noetic-python debian11 debian13
test-platforms:
	@bash $(ROOT)/test/platforms/run $(PLATFORMS)

# every JSON under bench/results/ that docs/benchmarks.md shows, then that page again (every
# benchmark runs; the target exits non-zero when one did: a target missed or a failure)
# (with obstacle_detector's and move_base's workspaces on top when `make obstacle-detector` and
# `make move-base` built them)
bench: setup
	@mkdir -p bench/results
	@$(ROS_ENV) && { [ ! -f $(OD_WS)/devel/setup.bash ] || source $(OD_WS)/devel/setup.bash --extend; } \
	  && { [ ! -f $(MB_WS)/devel/setup.bash ] || source $(MB_WS)/devel/setup.bash --extend; } \
	  && { $(SYS_PY) -m tiago_nav_tools.benchmarks $(BENCH); rc=$$?; $(SYS_PY) -m tiago_nav_tools.docs && exit $$rc; }

# builds tysik/obstacle_detector in .od_ws (not a Debian package), for `make bench BENCH=detection`
obstacle-detector: setup
	@bash bench/obstacle_detector/build.sh $(OD_WS)

# builds ROS's move_base in .mb_ws (Debian packages no navigation stack), for suites/people_move_base.yaml
move-base: setup
	@bash bench/move_base/build.sh $(MB_WS)

# the generated pages: docs/ros_api.md (from the code) and docs/benchmarks.md (from bench/results)
docs: setup
	@$(ROS_ENV) && $(SYS_PY) -m tiago_nav_tools.docs

# The batch evaluator: make evaluate SUITE=suites/course.yaml EVAL_OUT=dir [EVAL_ARGS="--workers 2"]
evaluate: setup
	@$(ROS_ENV) && rosrun tiago_nav evaluate $(SUITE) --out $(EVAL_OUT) $(EVAL_ARGS)

# catkin_test_changelog parses CHANGELOG.rst (REP 132) but skips sections it cannot read, so the
# next line also checks that the topmost version section is package.xml's version.
# vermin: no Python feature (syntax, stdlib module, function or argument) newer than Noetic's 3.8,
# annotations included as if evaluated; nodes/ and scripts/evaluate have no .py suffixes: named one by one.
lint: setup
	@$(ROS_ENV) && catkin_lint --strict -W2 $(WS)/src/tiago_nav
	@$(VENV)/bin/vermin -q -t=3.8- --violations --no-tips --eval-annotations --pessimistic \
	  setup.py src $(wildcard nodes/*) scripts/evaluate test bench scripts docs/make_graph.py \
	  || { echo "vermin: the code above needs a Python newer than 3.8 (Noetic's)"; exit 1; }
	@catkin_test_changelog $(ROOT)/CHANGELOG.rst 2>&1 >/dev/null \
	  | { grep -v '^DEBUG:changelog:Ignored non-compliant title' || true; } >&2
	@$(SYS_PY) -c 'import sys; from catkin_pkg.changelog import get_changelog_from_path as g; \
	  from catkin_pkg.package import parse_package as p; \
	  v = [x for x, _, _ in g(sys.argv[1]).foreach_version()]; w = p(sys.argv[2]).version; \
	  sys.exit(0 if v[:1] == [w] else "CHANGELOG.rst: topmost version section %s, package.xml %s" % (v[:1], w))' \
	  $(ROOT)/CHANGELOG.rst $(ROOT)

clean:
	rm -rf $(WS) $(VENV) $(OD_WS) $(MB_WS)
