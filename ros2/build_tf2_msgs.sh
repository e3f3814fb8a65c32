#!/usr/bin/env bash
# Build ROS 2's tf2_msgs message types (TFMessage, TF2Error) into the virtualenv of PYTHON.
#
# ROS 2 Jazzy's PyPI wheels (the `ros2` extra of laser-corners) have rclpy, the rosidl code
# generators and most message packages, but no tf2_msgs; without it the node cannot publish
# or read /tf. This script generates the package from ros2/interfaces/tf2_msgs with those
# wheels and the system's cmake and C/C++ compiler, and installs it into PYTHON's prefix
# (about 10 s). It does nothing when `import tf2_msgs.msg` already works (an earlier run, or a
# sourced ROS 2 installation); FORCE=1 rebuilds anyway.
#
#   pip install '.[ros2]' && ros2/build_tf2_msgs.sh .venv/bin/python
#
# Exit codes: 0 built or already importable; 1 the build failed; 3 a tool (cmake, a C/C++
# compiler) or the ros2 extra is missing (one line says which).
set -euo pipefail

PYTHON=${1:-python3}
if ! PYTHON=$("$PYTHON" -c "import sys; print(sys.executable)" 2>/dev/null); then
  echo "tf2_msgs: not built: ${1:-python3} is not a Python interpreter"
  exit 3
fi
HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
SOURCE="$HERE/interfaces/tf2_msgs"

if [ "${FORCE:-0}" != 1 ] && "$PYTHON" -c "import tf2_msgs.msg" 2>/dev/null; then
  echo "tf2_msgs: already importable by $PYTHON"
  exit 0
fi
for tool in cmake make cc c++; do
  if ! command -v "$tool" >/dev/null 2>&1; then
    echo "tf2_msgs: not built: no $tool here (needs cmake, make and a C/C++ compiler)"
    exit 3
  fi
done
if ! "$PYTHON" -c "import rclpy, geometry_msgs.msg, rosidl_generator_py, catkin_pkg" 2>/dev/null; then
  echo "tf2_msgs: not built: $PYTHON lacks the ros2 extra: pip install 'laser-corners[ros2]'"
  exit 3
fi
PREFIX=$("$PYTHON" -c "import sys; print(sys.prefix)")
BUILD=$(mktemp -d "${TMPDIR:-/tmp}/tf2_msgs_build.XXXXXX")
trap 'rm -rf "$BUILD"' EXIT

echo "tf2_msgs: building into $PREFIX"
if ! (cd "$BUILD" &&
  cmake "$SOURCE" -DCMAKE_INSTALL_PREFIX="$PREFIX" -DCMAKE_PREFIX_PATH="$PREFIX" \
    -DPython3_EXECUTABLE="$PYTHON" -DBUILD_TESTING=OFF -DCMAKE_BUILD_TYPE=Release \
    >"$BUILD/log.txt" 2>&1 &&
  cmake --build . -j "${JOBS:-2}" >>"$BUILD/log.txt" 2>&1 &&
  cmake --install . >>"$BUILD/log.txt" 2>&1); then
  tail -n 30 "$BUILD/log.txt"
  echo "tf2_msgs: build failed (log above)"
  exit 1
fi
if ! "$PYTHON" -c "import tf2_msgs.msg; tf2_msgs.msg.TFMessage()"; then
  echo "tf2_msgs: installed into $PREFIX but not importable by $PYTHON"
  exit 1
fi
echo "tf2_msgs: built; $PYTHON imports tf2_msgs.msg"
