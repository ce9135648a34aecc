# Sourced, not run: a Docker engine that answers, and the debian:bookworm-slim base image, for
# tests/containers/container_farm_test.sh and scripts/time-showcase.sh. No registry is reachable on
# the build machines, so the image is made locally with debootstrap, from the Debian mirror this
# machine's apt already installs from, when Docker does not have it.
#
# Each function returns 0 when done; otherwise it sets $bookworm_why and returns 1 where this
# machine cannot do it (no root, a tool or a mirror missing: a test skips) or 2 where it tried and
# failed (a test fails). Progress goes through the caller's log() when it has one.

bookworm_log() { if declare -F log >/dev/null; then log "$@"; else echo "$@"; fi; }

# Starts dockerd (as root, detached, so a CTest run does not wait for it; it keeps running) unless
# an engine already answers.
docker_engine_up() {
  docker info >/dev/null 2>&1 && return 0
  if ! { [ "$(id -u)" -eq 0 ] && command -v dockerd >/dev/null; }; then
    bookworm_why="no Docker engine answers, and starting dockerd needs root"
    return 1
  fi
  bookworm_log "starting dockerd (log: /tmp/tessera-dockerd.log)"
  (setsid dockerd >/tmp/tessera-dockerd.log 2>&1 </dev/null &)
  for _ in $(seq 1 60); do docker info >/dev/null 2>&1 && return 0; sleep 1; done
  tail -20 /tmp/tessera-dockerd.log
  bookworm_why="dockerd did not start (log above)"
  return 1
}

# The Debian mirror this machine's apt already installs from (a deb822 .sources stanza or a
# one-line sources.list entry for bookworm): the image comes from the same place, wherever that is.
apt_mirror() {
  local uri
  uri=$(awk '/^[[:space:]]*$/ {u = ""} /^URIs:/ {u = $2} /^Suites:/ && / bookworm( |$)/ && u != "" {print u; exit}' \
          /etc/apt/sources.list.d/*.sources 2>/dev/null)
  [ -n "$uri" ] || uri=$(awk '$1 == "deb" && / bookworm / {for (i = 2; i <= NF; i++) if ($i ~ /^[a-z]+:\/\//) {print $i; exit}}' \
                           /etc/apt/sources.list /etc/apt/sources.list.d/*.list 2>/dev/null | head -1)
  echo "$uri"
}

# debian:bookworm-slim in the engine, made with debootstrap when missing.
bookworm_slim_image() {
  docker image inspect debian:bookworm-slim >/dev/null 2>&1 && return 0
  if ! command -v debootstrap >/dev/null; then
    bookworm_why="debian:bookworm-slim is missing and debootstrap is not installed"
    return 1
  fi
  local mirror rootfs
  mirror=$(apt_mirror)
  if [ -z "$mirror" ]; then
    bookworm_why="debian:bookworm-slim is missing and apt's sources name no bookworm mirror to debootstrap from"
    return 1
  fi
  bookworm_log "making debian:bookworm-slim with debootstrap from $mirror"
  rootfs=$(mktemp -d /tmp/tessera-bookworm-rootfs.XXXXXX)
  if ! debootstrap --variant=minbase bookworm "$rootfs" "$mirror" >/tmp/tessera-debootstrap.log 2>&1; then
    tail -20 /tmp/tessera-debootstrap.log
    rm -rf "$rootfs"
    bookworm_why="debootstrap failed (log above)"
    return 2
  fi
  local rc=0
  tar -C "$rootfs" -c . | docker import - debian:bookworm-slim >/dev/null || rc=2
  rm -rf "$rootfs"
  [ "$rc" -eq 0 ] || bookworm_why="docker import of the debootstrap tree failed"
  return "$rc"
}
