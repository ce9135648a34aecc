#!/usr/bin/env bash
# Packs the farm benchmarks' programs (stripped) and the shared libraries they load, except the C
# library's own, into one folder laid out like a build folder, for a many-core machine that has
# no Tessera build and no development packages (its C library must be as new as this one's):
#
#   bench/farm/bundle.sh [--build DIR] OUT_DIR
#   LD_LIBRARY_PATH=OUT_DIR/lib bench/farm/scale.sh --build OUT_DIR
set -euo pipefail
HERE=$(cd "$(dirname "$0")" && pwd)
BUILD=$HERE/../../build
if [ "${1:-}" = "--build" ]; then BUILD=$2; shift 2; fi
[ $# -eq 1 ] || { sed -n '2,7p' "$0"; exit 2; }
OUT=$1
PROGRAMS="client/tessera server/tessera-server worker/tessera-worker bench/farm/coordinator_load bench/farm/first_tile_probe"
mkdir -p "$OUT/lib"
for p in $PROGRAMS; do
  [ -x "$BUILD/$p" ] || { echo "bundle.sh: $BUILD/$p is missing: build it first" >&2; exit 1; }
  mkdir -p "$OUT/$(dirname "$p")"
  strip -o "$OUT/$p" "$BUILD/$p"
done
# The C library, its loader and its parts stay the host's: mixing two of them in one process fails.
for p in $PROGRAMS; do ldd "$BUILD/$p"; done | awk '/=> \//{print $3}' | sort -u |
  grep -v -E '/(libc|libm|libpthread|libdl|librt|libresolv|ld-linux[^/]*)\.so' |
  while read -r lib; do cp -L "$lib" "$OUT/lib/"; done
echo "bundle.sh: $(ls "$OUT/lib" | wc -l) libraries, $(du -sh "$OUT" | cut -f1) in $OUT"
