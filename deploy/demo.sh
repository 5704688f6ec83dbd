#!/usr/bin/env bash
# The main job on a fresh Debian 12 machine: install dependencies, build, and run the cornell
# inverse problem on an embedded server with local workers (about a minute on 2 cores).
set -euo pipefail
cd "$(dirname "$0")/.."
bash deploy/setup.sh
bash deploy/build.sh
./build/bin/invr run "${INVR_DEMO_SCENE:-cornell}" -o out/demo
