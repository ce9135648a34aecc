#!/usr/bin/env bash
# Installs the Debian bookworm packages Tessera needs. Idempotent: only installs what is missing.
# Needs root (or sudo).
#
#   install-deps.sh              everything: build, run, test and benchmark (scripts/test.sh, CI)
#   install-deps.sh --programs   only what building and running the programs needs (tessera-server,
#                                tessera-worker, tessera): scripts/showcase.sh
#
# Any other arguments are more package names to install. This is the one list of packages: the
# sets below are its parts, and the full set is their union.
set -euo pipefail

# ---- the programs: compiler, build tools, the libraries they link (-dev: headers + shared libs) ----
# (g++ and make rather than build-essential, whose dpkg-dev brings Perl: a few seconds of a
# first install that building does not use; the full set below has build-essential.)
PROGRAM_PKGS=(
  g++ make cmake ninja-build pkg-config
  libgrpc++-dev protobuf-compiler-grpc libprotobuf-dev protobuf-compiler
  libembree-dev libtbb-dev libopenexr-dev libspdlog-dev libcli11-dev
  nlohmann-json3-dev libassimp-dev libsqlite3-dev libpng-dev libssl-dev
  libxxhash-dev zlib1g-dev  # the coordinator's tile records: XXH3-64 (older ones: zlib's CRC-32; server/tile_store.cpp)
  libhwy-dev  # Google Highway: SIMD (render/triangle_cluster_simd.cpp)
  libtinygltf-dev libjpeg-dev  # glTF scenes (lib/scene/gltf_*): tinygltf parses (header only, compiled in), libpng/libjpeg decode textures
  libcpp-httplib-dev prometheus-cpp-dev  # the coordinator's HTTP side (server/monitor, server/metrics): HTTP(S), Prometheus metrics
)

# ---- the tests and benchmarks (installed with no argument) ---------------------------------------
# Building them (GoogleTest, Google Benchmark); build-essential and git for working on the sources.
TEST_BUILD_PKGS=(build-essential git libgtest-dev libgmock-dev libbenchmark-dev)
# Independent checkers used by the tests (oiiotool/idiff, exrheader, Python gRPC client).
CHECK_PKGS=(openimageio-tools openexr python3-grpcio python3-grpc-tools python3-numpy python3-yaml)
CHECK_PKGS+=(openssl clang libclang-rt-14-dev)  # TLS tests make a throwaway CA; fuzz/run.sh (libFuzzer)
# tests/farm/farm_monitor_test: a real Prometheus scraping /metrics, the monitor in headless Chromium.
CHECK_PKGS+=(prometheus chromium chromium-driver python3-selenium)
# tests/farm/farm_slurm_test: a single-node Slurm on localhost places workers (docker/slurm).
CHECK_PKGS+=(slurm-wlm munge)
# python/ and blender/: the Python package's tests (pytest) and the add-on's, headless in Blender
# (xvfb: one test drives Blender's real UI in a virtual display). `pip install ./python` in a venv
# (python/README.md; its tests do it too) needs python3-venv, and python3-wheel for setuptools.
CHECK_PKGS+=(python3-pytest python3-venv python3-wheel blender xvfb xauth)
# Used by the benchmarks in bench/ only (pngquant is a GPL comparator, run, never linked).
BENCH_PKGS=(bc time pngquant gnuplot-nox povray)

want=("${PROGRAM_PKGS[@]}")
if [ "${1:-}" = --programs ]; then
  shift
  what="program"
else
  want+=("${TEST_BUILD_PKGS[@]}" "${CHECK_PKGS[@]}" "${BENCH_PKGS[@]}")
  what="all"
fi
want+=("$@")
missing=()
for p in "${want[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: $what packages present (${#want[@]})"
  exit 0
fi
SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"
echo "install-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
