#!/usr/bin/env bash
# Build activesurv_interfaces (ament_cmake + rosidl) into a wheel and install it into the venv.
# The PyPI Jazzy wheels install a ROS prefix into the venv itself, so the venv is both the
# AMENT_PREFIX_PATH the generators look in and the prefix the messages are installed to.
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
venv=${VENV:-$here/.venv}
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
unset _ROS_WHEELS_BOOTSTRAP_COMPLETE
export VIRTUAL_ENV=$venv AMENT_PREFIX_PATH=$venv CMAKE_PREFIX_PATH=$venv
# tf2_msgs (for /tf and /tf_static): the PyPI wheels lack it; a full ROS install has its own,
# which is used as it is. Built from the standard definitions in src/vendor/tf2_msgs.
if ! "$venv/bin/python" -c 'import tf2_msgs.msg' 2>/dev/null || [ -f "$venv/share/tf2_msgs/activesurv_vendored" ]; then
  "$venv/bin/python" -m pip wheel --disable-pip-version-check -q --no-build-isolation --no-deps \
    -w "$out" "$here/src/vendor/tf2_msgs"
  "$venv/bin/python" -m pip install --disable-pip-version-check -q --no-deps --force-reinstall "$out"/tf2_msgs-*.whl
  touch "$venv/share/tf2_msgs/activesurv_vendored"
fi
"$venv/bin/python" -m pip wheel --disable-pip-version-check -q --no-build-isolation --no-deps \
  -w "$out" "$here/src/activesurv_interfaces"
"$venv/bin/python" -m pip install --disable-pip-version-check -q --no-deps --force-reinstall "$out"/activesurv_interfaces-*.whl
