#!/usr/bin/env bash
# Compile the numba kernels once, at set-up (`make setup` runs this), so that a user's first command does not pay
# for it: numba caches them in the packages' __pycache__ (cache=True) and later processes load them. Each step is a
# small real run of a command a user calls; a failure here fails the set-up (the tools would fail the same way).
set -euo pipefail
BIN="$(cd "$(dirname "$0")/.." && pwd)/.venv/bin"
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
T="$(mktemp -d /tmp/compile_kernels.XXXXXX)"
trap 'rm -rf "$T"' EXIT
start=$SECONDS
echo "compiling numba kernels once (about a minute of CPU; cached for later runs)"
"$BIN/rod-deploy" grasp --ls 5 --kappa 0.2 --ks 1000 > /dev/null
printf '0 0\n0.05 0\n0.10 0\n' > "$T/line.txt"
printf 'length: 0.2\nradius: 0.002\nL_gb: 0.034\n' > "$T/rod.yaml"
"$BIN/rod-deploy" plan --pattern "$T/line.txt" --rod "$T/rod.yaml" --out "$T/traj.csv" > /dev/null
"$BIN/rod-deploy" simulate --traj "$T/traj.csv" --rod "$T/rod.yaml" --pattern "$T/line.txt" --edge-length 0.01 \
    --dt 0.05 --out "$T/deployed.csv" > /dev/null
"$BIN/rod-deploy" perceive --image "$ROOT/ros_ws/src/rod_deploy/rod_deploy/data/drawn_pattern.png" \
    --m-per-px 0.001 --out "$T/pattern.csv" > /dev/null
"$BIN/flex-ident" identify --bag "$ROOT/bags/example_loop6/bag" --experiment "$ROOT/bags/example_loop6/experiment.yaml" \
    --out "$T/ident" --max-iterations 1 --no-plots --no-diagnose --quiet > /dev/null
echo "numba kernels compiled in $((SECONDS - start)) s"
