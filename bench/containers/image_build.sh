#!/usr/bin/env bash
# The full container test: the images built by docker/Dockerfile exactly as users build them
# (compiling the project inside the image), then the same farm run as CI's container test
# (tests/containers/container_farm_test.sh, which CI runs with this host's programs in the images).
# About half an hour on a 2-core machine, most of it compiling. Prints one JSON line:
#   {"bench": "container_image_build", "image_build_s": ..., "total_s": ..., "cpu": "..."}
#
#   bench/containers/image_build.sh [BUILD_DIR]     # BUILD_DIR: default build/
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
build=$(cd "${1:-$root/build}" && pwd)
log=$(mktemp /tmp/tessera-image-build.XXXXXX.log)
start=$SECONDS
# No layer cache: the compile is what this measures.
TESSERA_CONTAINER_NO_CACHE=1 TESSERA_CONTAINER_BINARIES=source bash "$root/tests/containers/container_farm_test.sh" "$root" \
  "$build/client/tessera" "$build/server/tessera-server" "$build/worker/tessera-worker" 2>&1 | tee "$log"
status=${PIPESTATUS[0]}
image_s=$(grep -oE 'images built in [0-9]+ s' "$log" | grep -oE '[0-9]+' || echo null)
cpu=$(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ *//')
printf '{"bench": "container_image_build", "passed": %s, "image_build_s": %s, "total_s": %d, "cpu": "%s"}\n' \
  "$([ "$status" -eq 0 ] && echo true || echo false)" "$image_s" "$((SECONDS - start))" "$cpu"
rm -f "$log"
exit "$status"
