#!/usr/bin/env bash
# Builds with warnings as errors and runs every test (unit + CLI) with ctest.
set -euo pipefail
cd "$(dirname "$0")/.."
bash deploy/setup.sh
bash deploy/build.sh -DINVR_WERROR=ON
cd build && ctest --output-on-failure -j"$(nproc)"
