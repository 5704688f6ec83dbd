#!/usr/bin/env bash
# Installs every Debian 12 package that invr's build, tests, demo and charts need (clang and its
# runtime libraries for the fuzz targets of deploy/fuzz.sh: libFuzzer is in libclang-rt-14-dev;
# Slurm and munge for the real-Slurm test of deploy/slurm/invr.sbatch; openssl makes the TLS
# test's certificates; iproute2 gives `ip netns` for the multi-host test).
# Idempotent and non-interactive; run as root (or through sudo).
set -euo pipefail
export DEBIAN_FRONTEND=noninteractive

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi

PACKAGES=(
  build-essential cmake ninja-build ccache pkg-config git
  libembree-dev libtbb-dev
  libopenimageio-dev libopenexr-dev libimath-dev
  libprotobuf-dev protobuf-compiler
  libgrpc++-dev protobuf-compiler-grpc
  libspdlog-dev libfmt-dev libssl-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libnanoflann-dev libeigen3-dev libcli11-dev libtinyobjloader-dev nlohmann-json3-dev libpugixml-dev
  python3 python3-grpcio python3-matplotlib
  clang libclang-rt-14-dev
  slurm-wlm munge
  openssl iproute2 libcpp-httplib-dev
)

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "setup: all ${#PACKAGES[@]} packages already installed"
  exit 0
fi
echo "setup: installing ${missing[*]}"
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
echo "setup: done"
