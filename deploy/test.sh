#!/usr/bin/env bash
# Builds with warnings as errors, runs every test (unit, CLI, integration) with ctest, then the
# evaluation suite's smoke run.
set -euo pipefail
cd "$(dirname "$0")/.."
bash deploy/setup.sh
bash deploy/build.sh -DINVR_WERROR=ON
cd build && ctest --output-on-failure -j"$(nproc)"
cd ..
# The evaluation suite's smoke run (`invr eval --quick`, about a minute); the full suite is run by
# hand: see tests/bench/README.md.
bash tests/bench/eval_smoke.sh build/bin build/eval-quick
