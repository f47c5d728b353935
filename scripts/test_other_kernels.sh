#!/usr/bin/env bash
# Run the tests that do not start ROS nodes under each OpenBLAS kernel named on the command line
# (default: Sandybridge SkylakeX Prescott Haswell Zen), e.g. `bash scripts/test_other_kernels.sh SkylakeX`.
# A kernel this CPU cannot execute is skipped with a line saying so; any failing run fails the script.
# Needs the virtual environment of `make setup`.
set -uo pipefail
cd "$(dirname "$0")/.."
PY=.venv/bin/python
kernels=("$@")
[ ${#kernels[@]} -gt 0 ] || kernels=(Sandybridge SkylakeX Prescott Haswell Zen)
# ROS nodes and processes are not floating-point sensitive and are the slow part: left to `make test`. A test file
# is left out when it uses ROS (rclpy, the ros_context fixture, a ROS domain) or starts processes of the nodes.
mapfile -t files < <(grep -L -E 'rclpy|ros_context|ROS_DOMAIN_ID' ros_ws/src/*/test/test_*.py | grep -v process)
status=0
for kernel in "${kernels[@]}"; do
  if ! { OPENBLAS_CORETYPE=$kernel "$PY" -c \
      'import numpy as np; a = np.random.rand(200, 200); np.linalg.solve(a + 200 * np.eye(200), a @ a)'; } \
      >/dev/null 2>&1; then
    echo "OpenBLAS kernel $kernel: skipped, this CPU cannot execute it"
    continue
  fi
  echo "OpenBLAS kernel $kernel: the tests without ROS nodes"
  if ! OPENBLAS_CORETYPE=$kernel "$PY" -m pytest -q -p no:cacheprovider "${files[@]}"; then
    echo "OpenBLAS kernel $kernel: FAILED"
    status=1
  fi
done
exit $status
