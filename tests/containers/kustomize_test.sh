#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Every kustomization a user applies builds with kubectl's own kustomize (no cluster needed), and
# builds what it says: docker/k8s the base with its CPU autoscaler, docker/k8s/keda the same farm
# with a KEDA ScaledObject instead, docker/k8s/collect the collector alone (it goes beside either
# farm). validate_manifests.py checks the fields; this checks that kustomize accepts the layout (it
# refuses, for one, an overlay inside its base's folder).
# Skipped (77) where there is no kubectl.
set -uo pipefail
root=$1
if ! command -v kubectl > /dev/null; then
  echo "kustomize_test: no kubectl on this machine: skipped"
  exit 77
fi
fail=0
# kinds DIR: the kinds `kubectl kustomize DIR` builds, one "COUNT KIND" a line.
kinds() { kubectl kustomize "$root/$1" | sed -n 's/^kind: //p' | sort | uniq -c | awk '{print $1, $2}'; }
expect() {  # DIR, then the "COUNT KIND" lines it must build, exactly
  local dir=$1; shift
  local got want
  if ! got=$(kinds "$dir" 2>&1); then
    echo "FAIL: kubectl kustomize $dir: $got"; fail=1; return
  fi
  want=$(printf '%s\n' "$@" | sort -k2)
  got=$(echo "$got" | sort -k2)
  if [ "$got" != "$want" ]; then
    echo "FAIL: kubectl kustomize $dir builds"; echo "$got"; echo "expected"; echo "$want"; fail=1
  else
    echo "ok: kubectl kustomize $dir: $(echo $got)"
  fi
}
expect docker/k8s "2 Deployment" "1 HorizontalPodAutoscaler" "1 PersistentVolumeClaim" "1 Service"
expect docker/k8s/keda "2 Deployment" "1 PersistentVolumeClaim" "1 ScaledObject" "1 Service"
expect docker/k8s/collect "1 Deployment"
exit $fail
