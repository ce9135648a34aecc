#!/bin/sh
# Prints the Debian packages that own the shared libraries the given programs load, one per line,
# sorted: what a runtime image must install for them. Fails naming any library no package owns.
# Run where the programs were linked (the image's build stage, or a Debian bookworm host whose
# binaries go into an image: tests/containers/container_farm_test.sh).
#   docker/runtime-packages.sh PROGRAM...
set -eu
for lib in $(ldd "$@" | awk '$3 ~ /^\// {print $3}' | sort -u); do
  dpkg-query -S "$lib" 2>/dev/null || dpkg-query -S "$(readlink -f "$lib")" 2>/dev/null \
    || dpkg-query -S "/usr$lib" 2>/dev/null || { echo "no package owns $lib" >&2; exit 1; }
done | cut -d: -f1 | sort -u
