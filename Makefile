# SPDX-License-Identifier: Apache-2.0
# skynav: `make test` and `make demo` are the two commands a newcomer needs;
# both run `make setup` first, which does nothing when nothing changed.
SHELL := /bin/bash
PYTHON ?= python3.11
VENV := $(CURDIR)/.venv
BIN := $(VENV)/bin
STAMPS := $(VENV)/.skynav
PIP := $(BIN)/python -m pip --disable-pip-version-check
PY_PACKAGES := skynav_core skynav_bringup skynav_skyline skynav_sh skynav_localize \
               skynav_compass skynav_warping skynav_sim skynav_route skynav_viz
PY_PACKAGE_FILES := $(foreach p,$(PY_PACKAGES),$(p)/setup.py $(p)/setup.cfg $(p)/pyproject.toml $(p)/package.xml) \
                    $(shell find $(addsuffix /config,$(PY_PACKAGES)) \
                            $(addsuffix /launch,$(PY_PACKAGES)) -type f 2>/dev/null)
PY_PACKAGE_FILES += tools/link_data_files.py testing/pyproject.toml
MSG_FILES := $(wildcard skynav_msgs/msg/*.msg) $(wildcard skynav_msgs/action/*.action) skynav_msgs/CMakeLists.txt \
             skynav_msgs/package.xml cmake/strip_wheel_include_dirs.cmake tools/build_msgs.sh
TF2_MSG_FILES := vendor/tf2_msgs/msg/TFMessage.msg vendor/tf2_msgs/CMakeLists.txt vendor/tf2_msgs/package.xml \
                 cmake/strip_wheel_include_dirs.cmake tools/build_msgs.sh

.PHONY: setup test lint demo lock clean

## setup: virtualenv at .venv with ROS 2 Jazzy, skynav_msgs (and tf2_msgs where it lacks one) and the skynav packages
setup: $(STAMPS)/packages

$(BIN)/python:
	@$(PYTHON) -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))' 2>/dev/null || { \
	  echo "make setup: needs CPython 3.11 as '$(PYTHON)' (the ROS 2 Jazzy wheels on PyPI are" \
	       "built for it); run e.g. 'make setup PYTHON=/path/to/python3.11'" >&2; exit 1; }
	$(PYTHON) -m venv $(VENV)

$(STAMPS)/deps: requirements.txt constraints.txt | $(BIN)/python
	$(PIP) install --quiet -c constraints.txt -r requirements.txt
	@mkdir -p $(STAMPS) && touch $@

$(STAMPS)/msgs: $(STAMPS)/deps $(MSG_FILES)
	tools/build_msgs.sh $(VENV) build/skynav_msgs
	@touch $@

# tf2_msgs/msg/TFMessage (/tf_static) for a venv whose ROS wheels lack tf2_msgs; one that has a tf2_msgs keeps it.
$(STAMPS)/tf2_msgs: $(STAMPS)/deps $(TF2_MSG_FILES)
	@if [ -f $(VENV)/share/tf2_msgs/package.xml ] && ! grep -q 'vendored by skynav' $(VENV)/share/tf2_msgs/package.xml; \
	then echo "tf2_msgs is installed in $(VENV): the vendored copy is not built"; \
	else tools/build_msgs.sh $(VENV) build/tf2_msgs vendor/tf2_msgs; fi
	@touch $@

# Editable installs in compat mode put each package's folder on sys.path, so that the ROS package
# folders of the same name in the repository root (namespace packages to Python) cannot shadow them.
$(STAMPS)/packages: $(STAMPS)/msgs $(STAMPS)/tf2_msgs $(PY_PACKAGE_FILES)
	$(PIP) install --quiet --no-deps --no-build-isolation --config-settings editable_mode=compat \
	    $(addprefix -e ./,$(PY_PACKAGES)) -e ./testing
	$(BIN)/python tools/link_data_files.py $(VENV) $(PY_PACKAGES)
	@touch $@

## test: lint, format and type checks, then every test, unit and replay, with pytest's summary
# Two workers (the CI machine has two cores); a test file stays on one worker, so its fixtures are built once;
# files go out in the order conftest.py sorts them (the heavy ones first), not xdist's (most tests first).
TEST_WORKERS ?= 2
test: lint
	$(BIN)/python -m pytest -n $(TEST_WORKERS) --dist loadfile --no-loadscope-reorder

## lint: ruff's lint and format checks and mypy (configuration: ruff.toml, mypy.ini)
lint: setup
	$(BIN)/ruff check --quiet .
	$(BIN)/ruff format --check --quiet .
	$(BIN)/mypy

## demo: the node graph over bundled synthetic recordings, then teach and follow a route in the simulator; out/demo
demo: setup
	$(BIN)/skynav demo --out out/demo

## lock: rewrite constraints.txt from requirements.txt in a scratch virtualenv
lock:
	rm -rf build/lock-venv && $(PYTHON) -m venv build/lock-venv
	build/lock-venv/bin/python -m pip install --quiet --disable-pip-version-check -r requirements.txt
	build/lock-venv/bin/python tools/freeze.py > constraints.txt
	rm -rf build/lock-venv

clean:
	rm -rf $(VENV) build
