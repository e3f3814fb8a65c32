# The two commands of README: `make demo` and `make test`. Each creates .venv and installs
# what it needs, so they work on a fresh machine.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python

.PHONY: demo test test-ros lint bench clean ros1-deps tf2-msgs

# Debian's ROS 1 (bookworm: ros-core 1.16, rospy 1.15) for tests/ros/test_ros1_node.py. Installed
# with apt-get only when something is missing, as root (or passwordless sudo); without apt-get
# or root the ROS 1 tests skip and say why. See docs/ros.md.
ROS1_DEBS := ros-core python3-rospy python3-rosbag python3-sensor-msgs python3-geometry-msgs \
	python3-visualization-msgs

$(VENV)/.base: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --disable-pip-version-check -e .
	$(VENV)/bin/laser-corners warmup   # numba compiles the kernels once here (1-2 min on 2 cores, see README), not in the first run
	touch $@

# The test extra includes the ros2 extra: ROS 2 Jazzy's rclpy and messages as PyPI wheels, so
# tests/ros/test_ros2_node.py runs the node over real DDS in CI (no system ROS 2, no sourcing).
$(VENV)/.test: $(VENV)/.base
	$(PY) -m pip install --quiet --disable-pip-version-check -e '.[test]'
	touch $@

# tf2_msgs (/tf, /tf_static) is not among ROS 2's PyPI wheels: build it from
# ros2/interfaces/tf2_msgs into the venv with the rosidl wheels of the ros2 extra (cmake and a
# C/C++ compiler from the system; about 30 s, once). Without cmake or a compiler it says so and
# the node falls back to map_to_odom (its /tf tests then skip, and fail in CI). docs/ros.md
$(VENV)/.tf2_msgs: $(VENV)/.test ros2/build_tf2_msgs.sh $(wildcard ros2/interfaces/tf2_msgs/* ros2/interfaces/tf2_msgs/msg/*)
	@if [ -e $@ ]; then export FORCE=1; fi; \
	ros2/build_tf2_msgs.sh $(PY); status=$$?; \
	if [ $$status = 3 ]; then exit 0; fi; \
	if [ $$status != 0 ]; then exit $$status; fi; \
	touch $@

tf2-msgs: $(VENV)/.tf2_msgs

demo: $(VENV)/.base
	$(VENV)/bin/laser-corners demo --output demo.png

ros1-deps:
	@missing=""; for deb in $(ROS1_DEBS); do \
	  dpkg-query -W -f='$${Status}' $$deb 2>/dev/null | grep -q 'ok installed' || missing="$$missing $$deb"; \
	done; \
	if [ -z "$$missing" ]; then exit 0; fi; \
	if ! command -v apt-get >/dev/null 2>&1; then \
	  echo "ros1-deps: no apt-get here; ROS 1 tests will skip (missing:$$missing)"; exit 0; fi; \
	if [ "$$(id -u)" = 0 ]; then sudo=""; \
	elif sudo -n true 2>/dev/null; then sudo="sudo -n"; \
	else echo "ros1-deps: not root; ROS 1 tests will skip (missing:$$missing)"; exit 0; fi; \
	echo "ros1-deps: apt-get install$$missing"; \
	$$sudo env DEBIAN_FRONTEND=noninteractive apt-get update -qq && \
	$$sudo env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends $$missing

test: $(VENV)/.test $(VENV)/.tf2_msgs ros1-deps
	$(PY) -m ruff check src tests benchmarks
	$(PY) -m ruff format --check src tests benchmarks
	$(PY) -m pytest -rsx

# the ROS 1 and ROS 2 node tests alone, printing the end-to-end latencies (docs/ros.md)
test-ros: $(VENV)/.test $(VENV)/.tf2_msgs ros1-deps
	$(PY) -m pytest tests/ros -rs -s -q

lint: $(VENV)/.test
	$(PY) -m ruff check src tests benchmarks
	$(PY) -m ruff format --check src tests benchmarks

bench: $(VENV)/.base
	$(PY) benchmarks/bench_detector.py
	$(PY) benchmarks/bench_batch.py

clean:
	rm -rf $(VENV) .pytest_cache build *.egg-info src/*.egg-info
