#!/usr/bin/env bash
# The test command: installs what is missing, builds, and runs every test (unit tests beside the
# code, integration tests with real tessera-server/tessera-worker processes on loopback).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
bash scripts/build.sh
cd build
ctest --output-on-failure --timeout 600 -j "$(nproc 2>/dev/null || echo 2)" "$@"
