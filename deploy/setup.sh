#!/usr/bin/env bash
# Installs every Debian 12 package that invr's build, tests, demo, charts and Python package need
# (python3-grpcio, -protobuf, -numpy, -openimageio and -pytest for build/python/invr; clang and its
# runtime libraries for the fuzz targets of deploy/fuzz.sh: libFuzzer is in libclang-rt-14-dev;
# Slurm and munge for the real-Slurm test of deploy/slurm/invr.sbatch; openssl makes the TLS
# test's certificates; iproute2 gives `ip netns` for the multi-host test; Node.js, npm and kubectl
# render and validate the Kubernetes manifests offline, with the validator's npm packages
# installed here into deploy/k8s/validator/node_modules; libjs-chart.js is embedded in invr-server's
# dashboard at build time, and the dashboard's browser test drives Debian's chromium headless
# through the DevTools protocol with python3-websocket; python3-venv and libllvm19 let
# deploy/peers.sh install Mitsuba 3 from PyPI and run Dr.Jit's LLVM backend).
# Idempotent and non-interactive; run as root (or through sudo).
set -euo pipefail
export DEBIAN_FRONTEND=noninteractive

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi

# What building invr needs (the container image's build stage installs only these: --build-only).
BUILD_PACKAGES=(
  build-essential cmake ninja-build ccache pkg-config git
  libembree-dev libtbb-dev
  libopenimageio-dev libopenexr-dev libimath-dev
  libprotobuf-dev protobuf-compiler
  libgrpc++-dev protobuf-compiler-grpc
  libspdlog-dev libfmt-dev libssl-dev libcpp-httplib-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libnanoflann-dev libeigen3-dev libcli11-dev libtinyobjloader-dev nlohmann-json3-dev libpugixml-dev
  libjs-chart.js
)
# Tests, demo, charts, deployment checks and the profiles of docs/performance.md (perf).
PACKAGES=(
  "${BUILD_PACKAGES[@]}"
  python3 python3-grpcio python3-protobuf python3-numpy python3-matplotlib python3-pytest python3-openimageio
  clang libclang-rt-14-dev
  slurm-wlm munge
  openssl iproute2
  nodejs
  chromium python3-websocket
  linux-perf
  python3-venv libllvm19
)
if [ "${1:-}" = "--build-only" ]; then PACKAGES=("${BUILD_PACKAGES[@]}"); fi

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ "${1:-}" != "--build-only" ]; then
  # Tools that may come from elsewhere on a given machine (a nodejs that bundles npm, a kubectl
  # from another repository): Debian's packages only when the command is missing.
  command -v npm > /dev/null || missing+=(npm)
  command -v kubectl > /dev/null || missing+=(kubernetes-client)
fi
if [ ${#missing[@]} -eq 0 ]; then
  echo "setup: all ${#PACKAGES[@]} packages already installed"
else
  echo "setup: installing ${missing[*]}"
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi
if [ "${1:-}" != "--build-only" ]; then
  VALIDATOR="$(cd "$(dirname "$0")" && pwd)/k8s/validator"
  if [ ! -d "$VALIDATOR/node_modules/kubernetes-models" ]; then
    echo "setup: npm ci in $VALIDATOR (Kubernetes schema validator)"
    npm ci --prefix "$VALIDATOR" --no-audit --no-fund --loglevel=error
  fi
fi
echo "setup: done"
