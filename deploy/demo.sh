#!/usr/bin/env bash
# The main job on a fresh Debian 12 machine: install dependencies, build, render a zoo scene.
set -euo pipefail
cd "$(dirname "$0")/.."
bash deploy/setup.sh
bash deploy/build.sh
./build/client/invr render --scene "${INVR_DEMO_SCENE:-cornell}" --spp 128 --max-depth 5 -o out/demo.png
