#!/usr/bin/python3
"""Checks the container definitions that no test here can run: the Kubernetes manifests in
docker/k8s, its KEDA overlay (docker/k8s/keda), batch Job (docker/k8s/batch) and collector
(docker/k8s/collect) (no cluster on these machines), the collector's systemd unit
(docker/systemd/tessera-collect.service), and the structure of docker/compose.yaml, the root compose.yaml and
docker/Dockerfile. A KEDA query may only read metrics the coordinator registers
(server/metrics/farm_metrics.cpp).

Every YAML document is parsed; then the fields a cluster or compose would need are checked, and
the references between objects (Service selector -> pod labels, HPA -> Deployment, volume ->
PVC, worker -> coordinator Service, collector -> the share it writes, compose build target ->
Dockerfile stage).

  validate_manifests.py REPO_ROOT            check the real files (exit 0 ok, 1 problems)
  validate_manifests.py --self-test REPO_ROOT   break the real files in memory, one way at a time,
                                                and make sure every breakage is reported
"""
import copy
import os
import re
import shlex
import sys

try:
    import yaml
except ImportError:
    print("validate_manifests: needs PyYAML for /usr/bin/python3: apt-get install python3-yaml "
          "(scripts/install-deps.sh installs it)", file=sys.stderr)
    sys.exit(1)

WORKLOADS = ("Deployment", "StatefulSet", "DaemonSet")


def get(obj, path, default=None):
    """obj['a']['b'][0]... for a dotted path; default when any step is missing."""
    for part in path.split("."):
        if isinstance(obj, list):
            try:
                obj = obj[int(part)]
            except (ValueError, IndexError):
                return default
        elif isinstance(obj, dict):
            if part not in obj:
                return default
            obj = obj[part]
        else:
            return default
    return obj


def load_yaml_docs(path):
    with open(path) as f:
        return [d for d in yaml.safe_load_all(f) if d is not None]


# The base manifests are docker/k8s/base (keys "NAME"), docker/k8s's own kustomization builds on
# them (key "top/kustomization.yaml"), and beside them are the KEDA overlay, the batch Job and the
# collector (keys "keda/NAME", "batch/NAME", "collect/NAME").
K8S_EXTRAS = ("keda", "batch", "collect")


def load_k8s(root):
    k8s = os.path.join(root, "docker", "k8s")
    files = {}
    for sub, key in (("base", ""), ("", "top")) + tuple((x, x) for x in K8S_EXTRAS):
        folder = os.path.join(k8s, sub)
        for name in sorted(os.listdir(folder)):
            if name.endswith((".yaml", ".yml")):
                files[f"{key}/{name}" if key else name] = load_yaml_docs(os.path.join(folder, name))
    return files


def check_top(files):
    """docker/k8s/kustomization.yaml: `kubectl apply -k docker/k8s` is the base, nothing else."""
    kust = (files.get("top/kustomization.yaml") or [None])[0]
    if not kust:
        return ["docker/k8s: no kustomization.yaml (kubectl apply -k docker/k8s)"]
    if "base" not in (kust.get("resources") or []):
        return ["docker/k8s/kustomization.yaml: resources does not include the base (base)"]
    return []


def exported_metrics(root):
    """The metric names the coordinator registers (server/metrics/farm_metrics.cpp)."""
    with open(os.path.join(root, "server", "metrics", "farm_metrics.cpp")) as f:
        return set(re.findall(r'"(tessera_[a-z0-9_]+)"', f.read()))


# Set by main: what a scaler's query may name (histograms add _sum, _count and _bucket).
METRICS = set()


def number(text):
    try:
        return float(text)
    except (TypeError, ValueError):
        return None


def base_files(files):
    return {n: d for n, d in files.items() if "/" not in n}


def coordinator_service(files):
    """(name, ports as strings) of the base Service whose name names the coordinator."""
    for docs in base_files(files).values():
        for d in docs:
            if isinstance(d, dict) and d.get("kind") == "Service" and "coordinator" in get(d, "metadata.name", ""):
                return get(d, "metadata.name"), {str(p.get("port")) for p in get(d, "spec.ports") or []}
    return None, set()


def objects_in(files, folder, kind):
    """[(where, doc)] of the objects of `kind` in docker/k8s/<folder>/."""
    return [(f"docker/k8s/{n} {kind}/{get(d, 'metadata.name')}", d) for n, docs in files.items()
            if n.startswith(folder + "/") for d in docs if isinstance(d, dict) and d.get("kind") == kind]


def check_keda(files):
    """docker/k8s/keda: the base with its CPU HPA deleted and a ScaledObject on the workers."""
    errs = []
    base = {(d.get("kind"), get(d, "metadata.name")): d for docs in base_files(files).values() for d in docs
            if isinstance(d, dict)}
    kust = (files.get("keda/kustomization.yaml") or [None])[0]
    if not kust:
        return ["docker/k8s/keda: no kustomization.yaml (kubectl apply -k docker/k8s/keda)"]
    resources = kust.get("resources") or []
    if "../base" not in resources and "../base/" not in resources:
        errs.append("docker/k8s/keda/kustomization.yaml: resources does not include the base (../base)")
    for name in files:
        if name.startswith("keda/") and name != "keda/kustomization.yaml" and name[5:] not in resources:
            errs.append(f"docker/k8s/keda/kustomization.yaml: resources does not list {name[5:]}")
    deleted = set()
    for p in kust.get("patches") or []:
        try:
            doc = yaml.safe_load(p.get("patch", "")) if isinstance(p, dict) else None
        except yaml.YAMLError as e:
            errs.append(f"docker/k8s/keda/kustomization.yaml: a patch is not YAML: {e}")
            continue
        if isinstance(doc, dict) and doc.get("$patch") == "delete":
            deleted.add((doc.get("kind"), get(doc, "metadata.name")))
    for (kind, name), d in base.items():
        if kind == "HorizontalPodAutoscaler" and (kind, name) not in deleted:
            errs.append(f"docker/k8s/keda: the base's HorizontalPodAutoscaler {name} is not deleted "
                        "(KEDA makes its own; two would fight over the Deployment)")
    scaled = objects_in(files, "keda", "ScaledObject")
    if not scaled:
        errs.append("docker/k8s/keda: no ScaledObject")
    for w, d in scaled:
        if not str(d.get("apiVersion", "")).startswith("keda.sh/"):
            errs.append(f"{w}: apiVersion {d.get('apiVersion')!r} is not KEDA's (keda.sh/v1alpha1)")
        ref = get(d, "spec.scaleTargetRef") or {}
        target = base.get((ref.get("kind", "Deployment"), ref.get("name")))
        if target is None or "worker" not in ref.get("name", ""):
            errs.append(f"{w}: scaleTargetRef {ref.get('kind', 'Deployment')}/{ref.get('name')} is not the worker "
                        "Deployment of docker/k8s")
        lo, hi = get(d, "spec.minReplicaCount", 0), get(d, "spec.maxReplicaCount", 100)
        if not isinstance(lo, int) or not isinstance(hi, int) or not 0 <= lo <= hi or hi < 1:
            errs.append(f"{w}: needs 0 <= minReplicaCount ({lo}) <= maxReplicaCount ({hi}), maxReplicaCount >= 1")
        triggers = get(d, "spec.triggers") or []
        if not triggers:
            errs.append(f"{w}: no triggers")
        for t in triggers:
            if t.get("type") != "prometheus":
                errs.append(f"{w}: trigger type {t.get('type')!r}, expected prometheus")
                continue
            md = t.get("metadata") or {}
            if not re.match(r"https?://[^/\s]+", str(md.get("serverAddress", ""))):
                errs.append(f"{w}: serverAddress {md.get('serverAddress')!r} is not an http(s) URL")
            names = set(re.findall(r"\btessera_[a-z0-9_]+", str(md.get("query", ""))))
            if not names:
                errs.append(f"{w}: the query {md.get('query')!r} reads no tessera_ metric")
            for m in names:
                if m not in METRICS and re.sub(r"_(sum|count|bucket)$", "", m) not in METRICS:
                    errs.append(f"{w}: the query reads {m}, which the coordinator does not export")
            # KEDA takes thresholds as strings of numbers.
            if not isinstance(md.get("threshold"), str) or (number(md.get("threshold")) or 0) <= 0:
                errs.append(f"{w}: threshold {md.get('threshold')!r} is not a quoted number > 0")
            if "activationThreshold" in md and (not isinstance(md["activationThreshold"], str)
                                                or number(md["activationThreshold"]) is None
                                                or number(md["activationThreshold"]) < 0):
                errs.append(f"{w}: activationThreshold {md['activationThreshold']!r} is not a quoted number >= 0")
    return errs


def check_batch(files):
    """docker/k8s/batch: Indexed Jobs of workers that end with the farm's queue."""
    errs = []
    service, sports = coordinator_service(files)
    jobs = objects_in(files, "batch", "Job")
    if not jobs:
        errs.append("docker/k8s/batch: no Job")
    for w, d in jobs:
        if d.get("apiVersion") != "batch/v1":
            errs.append(f"{w}: apiVersion {d.get('apiVersion')!r}, expected batch/v1")
        if get(d, "spec.completionMode") != "Indexed":
            errs.append(f"{w}: completionMode {get(d, 'spec.completionMode')!r}, expected Indexed")
        completions, parallelism = get(d, "spec.completions"), get(d, "spec.parallelism")
        if not isinstance(completions, int) or not isinstance(parallelism, int) or not 1 <= parallelism <= completions:
            errs.append(f"{w}: needs 1 <= parallelism ({parallelism}) <= completions ({completions})")
        if not isinstance(get(d, "spec.backoffLimit"), int):
            errs.append(f"{w}: missing spec.backoffLimit")
        if get(d, "spec.template.spec.restartPolicy") not in ("Never", "OnFailure"):
            errs.append(f"{w}: restartPolicy must be Never or OnFailure for a Job")
        containers = get(d, "spec.template.spec.containers") or []
        if not containers:
            errs.append(f"{w}: no containers")
        for c in containers:
            cw = f"{w} container {c.get('name')}"
            if not c.get("image"):
                errs.append(f"{cw}: missing image")
            args = [str(a) for a in c.get("args") or []]
            idle = [a.split("=", 1)[1] if "=" in a else (args[i + 1] if i + 1 < len(args) else "")
                    for i, a in enumerate(args) if a.startswith("--exit-when-idle")]
            if not idle or (number(idle[0]) or 0) <= 0:
                errs.append(f"{cw}: no --exit-when-idle > 0: its pods would never finish and the Job never complete")
            env = {e.get("name"): e.get("value") for e in c.get("env") or []}
            host, _, port = str(env.get("TESSERA_COORDINATOR", "")).rpartition(":")
            if service is None or host.split(".")[0] != service or port not in sports:
                errs.append(f"{cw}: TESSERA_COORDINATOR={env.get('TESSERA_COORDINATOR')!r} is not the coordinator "
                            f"Service {service}:{'/'.join(sorted(sports))}")
            for res in ("cpu", "memory"):
                if not get(c, f"resources.requests.{res}"):
                    errs.append(f"{cw}: missing resources.requests.{res}")
            threads = [a for a in args if a.startswith("--threads")]
            cpu = str(get(c, "resources.requests.cpu", ""))
            if threads and cpu and not cpu.endswith("m") and threads[0].split("=")[-1] != cpu:
                errs.append(f"{cw}: {threads[0]} but requests.cpu {cpu}")
    return errs


def flag_values(args, flag):
    """The values of --flag=V and --flag V in args, in order."""
    out = []
    for i, a in enumerate(args):
        if a.startswith(flag + "="):
            out.append(a.split("=", 1)[1])
        elif a == flag and i + 1 < len(args):
            out.append(args[i + 1])
    return out


def check_collect(files):
    """docker/k8s/collect: `tessera collect` beside the farm, writing to the studio's share only."""
    errs = []
    kust = (files.get("collect/kustomization.yaml") or [None])[0]
    if not kust:
        return ["docker/k8s/collect: no kustomization.yaml (kubectl apply -k docker/k8s/collect)"]
    resources = kust.get("resources") or []
    for name in files:
        if name.startswith("collect/") and name != "collect/kustomization.yaml" and name[8:] not in resources:
            errs.append(f"docker/k8s/collect/kustomization.yaml: resources does not list {name[8:]}")
    for r in resources:
        if str(r).rstrip("/") in ("..", "../base", "../keda"):
            errs.append(f"docker/k8s/collect/kustomization.yaml: includes the farm ({r}): the collector goes beside "
                        "either farm (applied to the KEDA farm, the base would bring back its CPU autoscaler)")
    service, sports = coordinator_service(files)
    # The images the farm's workloads run: each carries the CLI, and `kustomize edit set image` names them.
    farm_images = {str(get(c, "image", "")).split(":")[0] for docs in base_files(files).values() for d in docs
                   if isinstance(d, dict) and d.get("kind") in WORKLOADS
                   for c in get(d, "spec.template.spec.containers") or []}
    collectors = []
    for w, d in objects_in(files, "collect", "Deployment"):
        pod = get(d, "spec.template.spec") or {}
        for c in pod.get("containers") or []:
            argv = [str(a) for a in (c.get("command") or []) + (c.get("args") or [])]
            if len(argv) >= 2 and os.path.basename(argv[0]) == "tessera" and argv[1] == "collect":
                collectors.append((f"{w} container {c.get('name')}", d, pod, c, argv))
    if not collectors:
        errs.append("docker/k8s/collect: no Deployment runs `tessera collect`")
    for cw, d, pod, c, argv in collectors:
        if str(c.get("image", "")).split(":")[0] not in farm_images:
            errs.append(f"{cw}: image {c.get('image')!r} is not one of the farm's images ({', '.join(sorted(farm_images))}), "
                        "which carry the tessera CLI")
        env = {e.get("name"): e for e in c.get("env") or []}
        addr = str(get(env, "TESSERA_COORDINATOR.value", ""))
        host, _, port = addr.rpartition(":")
        if service is None or host.split(".")[0] != service or port not in sports:
            errs.append(f"{cw}: TESSERA_COORDINATOR={addr!r} is not the coordinator Service "
                        f"{service}:{'/'.join(sorted(sports))}")
        token = env.get("TESSERA_CLIENT_TOKEN")
        if token is not None and not get(token, "valueFrom.secretKeyRef.name"):
            errs.append(f"{cw}: TESSERA_CLIENT_TOKEN is not taken from a Secret (a token in the manifest)")
        # The share: a PersistentVolumeClaim mounted writable. Every --under must lie on it, and
        # there must be one: without it the collector takes jobs written anywhere.
        volumes = {v.get("name"): v for v in pod.get("volumes") or []}
        shares = []
        for m in c.get("volumeMounts") or []:
            if get(volumes.get(m.get("name"), {}), "persistentVolumeClaim.claimName"):
                if m.get("readOnly"):
                    errs.append(f"{cw}: the share {m.get('mountPath')} is mounted readOnly")
                else:
                    shares.append(str(m.get("mountPath", "")).rstrip("/") + "/")
        if not shares:
            errs.append(f"{cw}: mounts no PersistentVolumeClaim to write the frames to (the studio's share)")
        unders = flag_values(argv, "--under")
        if not unders:
            errs.append(f"{cw}: no --under: it would take every job, and write those outside the share into the container")
        for u in unders:
            if not any((u.rstrip("/") + "/").startswith(sh) for sh in shares):
                errs.append(f"{cw}: --under {u} is not on a share it mounts ({', '.join(shares) or 'none'})")
        if not get(pod, "securityContext.runAsNonRoot") or not get(pod, "securityContext.runAsUser"):
            errs.append(f"{cw}: the pod does not run as a non-root uid (runAsNonRoot, runAsUser)")
        if get(pod, "securityContext.fsGroup") is not None:
            errs.append(f"{cw}: fsGroup on a pod that mounts the studio's share (kubelet may change the group of every file on it)")
        if get(c, "securityContext.readOnlyRootFilesystem") is not True:
            errs.append(f"{cw}: readOnlyRootFilesystem is not true: a frame whose pattern lies off the share would be "
                        "written into the container, acknowledged and lost")
        grace = pod.get("terminationGracePeriodSeconds")
        if not isinstance(grace, int) or grace < 30:
            errs.append(f"{cw}: terminationGracePeriodSeconds {grace!r}: set it, >= 30, to cover writing one frame")
        for res in ("cpu", "memory"):
            if not get(c, f"resources.requests.{res}"):
                errs.append(f"{cw}: missing resources.requests.{res}")
    return errs


def load_unit(path):
    """A systemd unit as {section: {key: [values, in order]}} (comments and blank lines skipped)."""
    unit, section = {}, None
    with open(path) as f:
        for line in f:
            line = line.strip()
            if not line or line[0] in "#;":
                continue
            if line.startswith("[") and line.endswith("]"):
                section = unit.setdefault(line[1:-1], {})
            elif "=" in line and section is not None:
                key, value = line.split("=", 1)
                section.setdefault(key.strip(), []).append(value.strip())
    return unit


def seconds(text):
    """systemd's time span ("120", "90s", "2min", "1min 30s", "infinity") in seconds; None if unreadable."""
    if str(text).strip() == "infinity":
        return float("inf")
    total, units = 0, {"": 1, "s": 1, "sec": 1, "m": 60, "min": 60, "h": 3600}
    for n, u in re.findall(r"(\d+)\s*([a-z]*)", str(text)):
        if u not in units:
            return None
        total += int(n) * units[u]
    return total if re.fullmatch(r"(\s*\d+\s*[a-z]*)+", str(text)) else None


def check_unit(unit, where="docker/systemd/tessera-collect.service"):
    """The collector on a host: `tessera collect --under SHARE`, bound to the share's mount, the
    file system read-only but for it, restarted, and given time to finish a frame on SIGTERM."""
    errs = []
    svc, u = unit.get("Service", {}), unit.get("Unit", {})
    last = lambda sec, key, default=None: (sec.get(key) or [default])[-1]
    start = last(svc, "ExecStart", "")
    try:
        argv = shlex.split(start)
    except ValueError:
        argv = []
    if len(argv) < 2 or not argv[0].startswith("/") or os.path.basename(argv[0]) != "tessera" or argv[1] != "collect":
        errs.append(f"{where}: ExecStart={start!r} does not run /.../tessera collect")
    unders = flag_values(argv, "--under")
    paths = lambda values: [v.lstrip("-+") for val in values for v in val.split()]
    writable = paths(svc.get("ReadWritePaths", []))
    mounts = paths(u.get("RequiresMountsFor", []))
    checked = [a for pre in svc.get("ExecStartPre", []) for a in shlex.split(pre)[1:]
               if "mountpoint" in pre and a.startswith("/")]
    within = lambda path, roots: any((path.rstrip("/") + "/").startswith(r.rstrip("/") + "/") for r in roots)
    if not unders:
        errs.append(f"{where}: no --under: it would take every job, and write those off the share")
    for d in unders:
        if not within(d, writable):
            errs.append(f"{where}: --under {d} is not in ReadWritePaths ({' '.join(writable) or 'none'})")
        if not within(d, mounts):
            errs.append(f"{where}: --under {d} is not under RequiresMountsFor ({' '.join(mounts) or 'none'}): "
                        "not bound to the share's mount")
        if not within(d, checked):
            errs.append(f"{where}: no ExecStartPre=mountpoint check of the share of --under {d}: an unmounted "
                        "share's empty directory would take the frames")
    for key, want in (("ProtectSystem", "strict"), ("NoNewPrivileges", "yes"), ("PrivateTmp", "yes"),
                      ("Restart", "always"), ("KillSignal", "SIGTERM")):
        got = last(svc, key, "SIGTERM" if key == "KillSignal" else None)
        if got != want:
            errs.append(f"{where}: {key}={got}, expected {want}")
    stop = seconds(last(svc, "TimeoutStopSec", "90"))
    if stop is None or stop < 30:
        errs.append(f"{where}: TimeoutStopSec={last(svc, 'TimeoutStopSec')}: at least 30 s, to finish writing a frame")
    if last(svc, "User") in (None, "root", "0") or last(svc, "DynamicUser") in ("yes", "true"):
        errs.append(f"{where}: User={last(svc, 'User')}: run as a dedicated user with a fixed uid (the share sees it)")
    if not any(e.startswith("-") for e in svc.get("EnvironmentFile", [])):
        errs.append(f"{where}: no optional EnvironmentFile=- (TESSERA_COORDINATOR, the token file)")
    after = " ".join(u.get("After", []))
    for target in ("network-online.target", "remote-fs.target"):
        if target not in after.split():
            errs.append(f"{where}: not After={target}")
    if "multi-user.target" not in " ".join(unit.get("Install", {}).get("WantedBy", [])).split():
        errs.append(f"{where}: not WantedBy=multi-user.target (systemctl enable)")
    return errs


def check_k8s(files):
    errs = []
    objects = []  # (file, doc)
    kustomization = None
    files = base_files(files)
    for name, docs in files.items():
        for i, d in enumerate(docs):
            where = f"docker/k8s/base/{name} document {i + 1}"
            if not isinstance(d, dict):
                errs.append(f"{where}: not a mapping")
                continue
            if d.get("kind") == "Kustomization":
                kustomization = (name, d)
                continue
            for field in ("apiVersion", "kind", "metadata.name"):
                if not get(d, field):
                    errs.append(f"{where}: missing {field}")
            objects.append((f"docker/k8s/base/{name} {d.get('kind')}/{get(d, 'metadata.name')}", d))

    by_kind = {}
    for where, d in objects:
        by_kind.setdefault(d.get("kind"), []).append((where, d))

    if kustomization is None:
        errs.append("docker/k8s/base: no kustomization.yaml")
    else:
        listed = set(kustomization[1].get("resources") or [])
        for name in files:
            if name != kustomization[0] and name not in listed:
                errs.append(f"docker/k8s/base/{kustomization[0]}: resources does not list {name}")
        for r in listed:
            if r not in files:
                errs.append(f"docker/k8s/base/{kustomization[0]}: lists {r}, which does not exist")

    pvcs = {get(d, "metadata.name"): (w, d) for w, d in by_kind.get("PersistentVolumeClaim", [])}
    for w, d in pvcs.values():
        if not get(d, "spec.accessModes"):
            errs.append(f"{w}: missing spec.accessModes")
        if not get(d, "spec.resources.requests.storage"):
            errs.append(f"{w}: missing spec.resources.requests.storage")

    workloads = {}
    for kind in WORKLOADS:
        for w, d in by_kind.get(kind, []):
            workloads[get(d, "metadata.name")] = (w, d)
            match = get(d, "spec.selector.matchLabels") or {}
            labels = get(d, "spec.template.metadata.labels") or {}
            if not match:
                errs.append(f"{w}: missing spec.selector.matchLabels")
            for k, v in match.items():
                if labels.get(k) != v:
                    errs.append(f"{w}: selector {k}={v} does not match the pod template labels {labels}")
            containers = get(d, "spec.template.spec.containers") or []
            if not containers:
                errs.append(f"{w}: no containers")
            volumes = {v.get("name"): v for v in get(d, "spec.template.spec.volumes") or []}
            claim_templates = {get(t, "metadata.name") for t in get(d, "spec.volumeClaimTemplates") or []}
            for c in containers:
                cw = f"{w} container {c.get('name')}"
                for field in ("name", "image"):
                    if not c.get(field):
                        errs.append(f"{cw}: missing {field}")
                if not c.get("readinessProbe") and not c.get("livenessProbe"):
                    errs.append(f"{cw}: no readinessProbe or livenessProbe")
                for probe in ("readinessProbe", "livenessProbe", "startupProbe"):
                    p = c.get(probe)
                    if p is not None and not any(k in p for k in ("grpc", "exec", "httpGet", "tcpSocket")):
                        errs.append(f"{cw}: {probe} has no grpc/exec/httpGet/tcpSocket handler")
                    if p is not None and "grpc" in p:
                        ports = {pp.get("containerPort") for pp in c.get("ports") or []}
                        if get(p, "grpc.port") not in ports:
                            errs.append(f"{cw}: {probe} grpc port {get(p, 'grpc.port')} is not a containerPort {sorted(ports)}")
                for res in ("cpu", "memory"):
                    if not get(c, f"resources.requests.{res}"):
                        errs.append(f"{cw}: missing resources.requests.{res}")
                for m in c.get("volumeMounts") or []:
                    vol = volumes.get(m.get("name"))
                    if vol is None and m.get("name") not in claim_templates:
                        errs.append(f"{cw}: mounts volume {m.get('name')}, which the pod does not define")
                    claim = get(vol or {}, "persistentVolumeClaim.claimName")
                    if claim is not None and claim not in pvcs:
                        errs.append(f"{cw}: volume {m.get('name')} claims {claim}, which no PersistentVolumeClaim defines")

    # The coordinator: a workload mounting persistent storage at the data directory, with a port.
    coordinators = [(n, w, d) for n, (w, d) in workloads.items() if "coordinator" in n]
    if len(coordinators) != 1:
        errs.append(f"docker/k8s: expected one coordinator workload, found {[n for n, _, _ in coordinators]}")
    coord_ports = {}
    coord_labels = {}
    for n, w, d in coordinators:
        if d.get("kind") == "Deployment" and get(d, "spec.replicas", 1) != 1:
            errs.append(f"{w}: a coordinator Deployment must have exactly 1 replica")
        coord_labels = get(d, "spec.template.metadata.labels") or {}
        for c in get(d, "spec.template.spec.containers") or []:
            for p in c.get("ports") or []:
                coord_ports[p.get("name")] = p.get("containerPort")
                coord_ports[p.get("containerPort")] = p.get("containerPort")
            if not coord_ports:
                errs.append(f"{w} container {c.get('name')}: no ports")
            if not c.get("livenessProbe"):
                errs.append(f"{w} container {c.get('name')}: the coordinator needs a livenessProbe")
            persistent = False
            volumes = {v.get("name"): v for v in get(d, "spec.template.spec.volumes") or []}
            templates = {get(t, "metadata.name") for t in get(d, "spec.volumeClaimTemplates") or []}
            for m in c.get("volumeMounts") or []:
                if m.get("mountPath") == "/var/lib/tessera" and (
                        get(volumes.get(m.get("name"), {}), "persistentVolumeClaim.claimName") or m.get("name") in templates):
                    persistent = True
            if not persistent:
                errs.append(f"{w} container {c.get('name')}: /var/lib/tessera is not on a PersistentVolumeClaim")

    services = {get(d, "metadata.name"): (w, d) for w, d in by_kind.get("Service", [])}
    coord_service = None
    for name, (w, d) in services.items():
        sel = get(d, "spec.selector") or {}
        if not sel:
            errs.append(f"{w}: missing spec.selector")
            continue
        pods = [wn for wn, (_, wd) in workloads.items()
                if all((get(wd, "spec.template.metadata.labels") or {}).get(k) == v for k, v in sel.items())]
        if not pods:
            errs.append(f"{w}: selector {sel} matches no pod template")
        if sel and all(coord_labels.get(k) == v for k, v in sel.items()):
            coord_service = (name, d)
            for p in get(d, "spec.ports") or []:
                if p.get("targetPort", p.get("port")) not in coord_ports:
                    errs.append(f"{w}: targetPort {p.get('targetPort')} is not a coordinator containerPort")
        if not get(d, "spec.ports"):
            errs.append(f"{w}: missing spec.ports")
    if coord_service is None:
        errs.append("docker/k8s: no Service selects the coordinator pods")

    # Workers: find the coordinator through its Service.
    workers = [(n, w, d) for n, (w, d) in workloads.items() if "worker" in n]
    if not workers:
        errs.append("docker/k8s: no worker workload")
    for n, w, d in workers:
        for c in get(d, "spec.template.spec.containers") or []:
            env = {e.get("name"): e.get("value") for e in c.get("env") or []}
            addr = env.get("TESSERA_COORDINATOR", "")
            if coord_service is not None:
                host, _, port = addr.rpartition(":")
                sports = {str(p.get("port")) for p in get(coord_service[1], "spec.ports") or []}
                if host.split(".")[0] != coord_service[0] or port not in sports:
                    errs.append(f"{w} container {c.get('name')}: TESSERA_COORDINATOR={addr!r} is not the "
                                f"coordinator Service {coord_service[0]}:{'/'.join(sorted(sports))}")
            threads = [a for a in c.get("args") or [] if str(a).startswith("--threads")]
            cpu = str(get(c, "resources.requests.cpu", ""))
            if threads and cpu and not cpu.endswith("m") and threads[0].split("=")[-1] != cpu:
                errs.append(f"{w} container {c.get('name')}: {threads[0]} but requests.cpu {cpu}")

    hpas = by_kind.get("HorizontalPodAutoscaler", [])
    if not hpas:
        errs.append("docker/k8s: no HorizontalPodAutoscaler for the workers")
    for w, d in hpas:
        ref = get(d, "spec.scaleTargetRef") or {}
        target = workloads.get(ref.get("name"))
        if target is None or target[1].get("kind") != ref.get("kind"):
            errs.append(f"{w}: scaleTargetRef {ref.get('kind')}/{ref.get('name')} is not a workload defined here")
        elif "worker" not in ref.get("name", ""):
            errs.append(f"{w}: scales {ref.get('name')}, not the workers")
        lo, hi = get(d, "spec.minReplicas", 1), get(d, "spec.maxReplicas")
        if not isinstance(hi, int) or not isinstance(lo, int) or not 1 <= lo <= hi:
            errs.append(f"{w}: needs 1 <= minReplicas ({lo}) <= maxReplicas ({hi})")
        if not get(d, "spec.metrics"):
            errs.append(f"{w}: missing spec.metrics")
        for m in get(d, "spec.metrics") or []:
            res = get(m, "resource.name")
            if m.get("type") == "Resource" and target is not None:
                for c in get(target[1], "spec.template.spec.containers") or []:
                    if not get(c, f"resources.requests.{res}"):
                        errs.append(f"{w}: scales on {res} utilization but {c.get('name')} requests no {res}")
    return errs


def dockerfile_stages(root):
    """{stage name: [instruction lines]} of docker/Dockerfile, continuation lines joined."""
    with open(os.path.join(root, "docker", "Dockerfile")) as f:
        text = re.sub(r"\\\n", " ", f.read())
    stages, current = {}, None
    for line in text.splitlines():
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        m = re.match(r"FROM\s+(\S+)(?:\s+AS\s+(\S+))?", line, re.I)
        if m:
            current = m.group(2) or f"stage{len(stages)}"
            stages[current] = [line]
        elif current:
            stages[current].append(line)
    return stages


def check_dockerfile(stages):
    errs = []
    first = next(iter(stages.values()), [""])[0]
    if not re.match(r"FROM\s+debian:bookworm-slim\b", first, re.I):
        errs.append(f"docker/Dockerfile: first stage is {first!r}, expected FROM debian:bookworm-slim")

    def inherited(stage, prefix):
        """Instructions starting with prefix in the stage or the stages it is built FROM."""
        out = []
        while stage in stages:
            out += [l for l in stages[stage] if l.upper().startswith(prefix)]
            stage = stages[stage][0].split()[1]
        return out

    for stage in ("server", "worker"):
        if stage not in stages:
            errs.append(f"docker/Dockerfile: no stage named {stage}")
            continue
        for prefix in ("HEALTHCHECK", "STOPSIGNAL", "USER", "ENTRYPOINT"):
            if not inherited(stage, prefix):
                errs.append(f"docker/Dockerfile: stage {stage} has no {prefix}")
        users = inherited(stage, "USER")
        if users and users[0].split()[1] in ("root", "0"):
            errs.append(f"docker/Dockerfile: stage {stage} runs as root")
        if inherited(stage, "STOPSIGNAL") and "SIGTERM" not in inherited(stage, "STOPSIGNAL")[0]:
            errs.append(f"docker/Dockerfile: stage {stage} does not stop with SIGTERM")
        if any("-dev" in l for l in inherited(stage, "RUN") if "apt-get install" in l):
            errs.append(f"docker/Dockerfile: stage {stage} installs -dev packages")
    if "server" in stages and not inherited("server", "VOLUME"):
        errs.append("docker/Dockerfile: the server stage declares no data VOLUME")
    return errs


def check_compose(compose, root_compose, stages):
    errs = []
    services = compose.get("services") or {}
    for name in ("coordinator", "worker"):
        if name not in services:
            errs.append(f"docker/compose.yaml: no service {name}")
    coord = services.get("coordinator") or {}
    worker = services.get("worker") or {}
    for sname, s in services.items():
        b = s.get("build") or {}
        if not s.get("image"):
            errs.append(f"docker/compose.yaml: service {sname} has no image name")
        if b.get("target") not in stages:
            errs.append(f"docker/compose.yaml: service {sname} builds target {b.get('target')!r}, "
                        f"not a Dockerfile stage ({', '.join(stages)})")
        if b.get("context") != "..":
            errs.append(f"docker/compose.yaml: service {sname} build context must be the repository root (..)")
    if not any(re.search(r":7878(/tcp)?$", str(p)) for p in coord.get("ports") or []):
        errs.append("docker/compose.yaml: the coordinator does not publish port 7878")
    named = set((compose.get("volumes") or {}).keys())
    mounts = [str(v).split(":") for v in coord.get("volumes") or []]
    if not any(len(m) >= 2 and m[0] in named and m[1] == "/var/lib/tessera" for m in mounts):
        errs.append("docker/compose.yaml: /var/lib/tessera of the coordinator is not on a named volume")
    listen = [a for a in coord.get("command") or [] if str(a).startswith("--listen")]
    if not listen or "0.0.0.0:7878" not in listen[0]:
        errs.append("docker/compose.yaml: the coordinator must listen on 0.0.0.0:7878 to be reachable")
    env = worker.get("environment") or {}
    if isinstance(env, list):
        env = dict(e.split("=", 1) for e in env)
    if env.get("TESSERA_COORDINATOR") != "coordinator:7878":
        errs.append(f"docker/compose.yaml: worker TESSERA_COORDINATOR={env.get('TESSERA_COORDINATOR')!r}, "
                    "expected the service name coordinator:7878")
    if "ports" in worker or "container_name" in worker:
        errs.append("docker/compose.yaml: a worker with ports or container_name cannot be scaled")
    # The root compose.yaml: only extends docker/compose.yaml, every service of it.
    rs = root_compose.get("services") or {}
    for name in services:
        ext = get(rs, f"{name}.extends") or {}
        if ext.get("file") != "docker/compose.yaml" or ext.get("service") != name:
            errs.append(f"compose.yaml: service {name} does not extend docker/compose.yaml's {name}")
    for name in named:
        if name not in (root_compose.get("volumes") or {}):
            errs.append(f"compose.yaml: does not declare volume {name}")
    return errs


def check_all(k8s, compose, root_compose, stages, unit):
    return (check_k8s(k8s) + check_top(k8s) + check_keda(k8s) + check_batch(k8s) + check_collect(k8s)
            + check_unit(unit) + check_dockerfile(stages)
            + check_compose(compose, root_compose, stages))


def self_test(k8s, compose, root_compose, stages, unit):
    """Each breakage below must be reported; the unbroken files must pass."""
    def find(files, kind, name_part):
        for docs in files.values():
            for d in docs:
                if d.get("kind") == kind and name_part in get(d, "metadata.name", ""):
                    return d
        raise KeyError(f"{kind} {name_part}")

    def container(d):
        return get(d, "spec.template.spec.containers.0")

    breakages = {
        "HPA targets another Deployment": lambda k, c, r, s: find(k, "HorizontalPodAutoscaler", "worker")["spec"]["scaleTargetRef"].update(name="tessera-workers"),
        "Service selector misses the pods": lambda k, c, r, s: find(k, "Service", "coordinator")["spec"]["selector"].update({"app.kubernetes.io/component": "coord"}),
        "worker has no CPU request": lambda k, c, r, s: container(find(k, "Deployment", "worker"))["resources"]["requests"].pop("cpu"),
        "coordinator has no probes": lambda k, c, r, s: [container(find(k, "Deployment", "coordinator")).pop(p) for p in ("readinessProbe", "livenessProbe")],
        "coordinator has no image": lambda k, c, r, s: container(find(k, "Deployment", "coordinator")).pop("image"),
        "PVC has no storage request": lambda k, c, r, s: find(k, "PersistentVolumeClaim", "coordinator")["spec"].pop("resources"),
        "volume claims an unknown PVC": lambda k, c, r, s: get(find(k, "Deployment", "coordinator"), "spec.template.spec.volumes.0")["persistentVolumeClaim"].update(claimName="other"),
        "object without a name": lambda k, c, r, s: find(k, "Service", "coordinator")["metadata"].pop("name"),
        "worker points elsewhere": lambda k, c, r, s: container(find(k, "Deployment", "worker"))["env"][0].update(value="localhost:7878"),
        "compose worker uses localhost": lambda k, c, r, s: c["services"]["worker"]["environment"].update(TESSERA_COORDINATOR="localhost:7878"),
        "compose coordinator port not published": lambda k, c, r, s: c["services"]["coordinator"].pop("ports"),
        "compose volume not declared": lambda k, c, r, s: c.pop("volumes"),
        "compose builds a missing stage": lambda k, c, r, s: c["services"]["worker"]["build"].update(target="wrker"),
        "root compose does not extend": lambda k, c, r, s: r["services"]["worker"].pop("extends"),
        "worker image runs as root": lambda k, c, r, s: s["runtime"].__setitem__(s["runtime"].index(next(l for l in s["runtime"] if l.startswith("USER"))), "USER root"),
        "server image has no HEALTHCHECK": lambda k, c, r, s: s.__setitem__("server", [l for l in s["server"] if not l.startswith("HEALTHCHECK")]),
        "ScaledObject scales another Deployment": lambda k, c, r, s: find(k, "ScaledObject", "worker")["spec"]["scaleTargetRef"].update(name="tessera-coordinator"),
        "ScaledObject reads a metric nobody exports": lambda k, c, r, s: get(find(k, "ScaledObject", "worker"), "spec.triggers.0.metadata").update(query="sum(tessera_queue_depth)"),
        "ScaledObject threshold not a quoted number": lambda k, c, r, s: get(find(k, "ScaledObject", "worker"), "spec.triggers.0.metadata").update(threshold=480),
        "KEDA overlay keeps the CPU HPA": lambda k, c, r, s: k["keda/kustomization.yaml"][0].pop("patches"),
        "KEDA overlay without the base": lambda k, c, r, s: k["keda/kustomization.yaml"][0].update(resources=["scaledobject.yaml"]),
        "docker/k8s without the base": lambda k, c, r, s: k["top/kustomization.yaml"][0].update(resources=["worker.yaml"]),
        "batch Job never exits when idle": lambda k, c, r, s: container(find(k, "Job", "worker"))["args"].pop(),
        "batch Job not Indexed": lambda k, c, r, s: find(k, "Job", "worker")["spec"].pop("completionMode"),
        "batch Job points elsewhere": lambda k, c, r, s: container(find(k, "Job", "worker"))["env"][0].update(value="localhost:7878"),
        "collect overlay includes the farm": lambda k, c, r, s: k["collect/kustomization.yaml"][0]["resources"].append("../base"),
        "collector does not run tessera collect": lambda k, c, r, s: container(find(k, "Deployment", "collector")).update(command=["tessera", "watch"]),
        "collector image without the CLI": lambda k, c, r, s: container(find(k, "Deployment", "collector")).update(image="busybox:latest"),
        "collector points elsewhere": lambda k, c, r, s: container(find(k, "Deployment", "collector"))["env"][0].update(value="localhost:7878"),
        "collector token in the manifest": lambda k, c, r, s: container(find(k, "Deployment", "collector"))["env"][1].update(value="s3cret", valueFrom=None),
        "collector without --under": lambda k, c, r, s: container(find(k, "Deployment", "collector")).update(args=[]),
        "collector --under off the share": lambda k, c, r, s: container(find(k, "Deployment", "collector")).update(args=["--under", "/home/"]),
        "collector share not a PVC": lambda k, c, r, s: get(find(k, "Deployment", "collector"), "spec.template.spec.volumes.0").update(persistentVolumeClaim=None, emptyDir={}),
        "collector share read-only": lambda k, c, r, s: container(find(k, "Deployment", "collector"))["volumeMounts"][0].update(readOnly=True),
        "collector root file system writable": lambda k, c, r, s: container(find(k, "Deployment", "collector"))["securityContext"].pop("readOnlyRootFilesystem"),
        "collector with fsGroup on the share": lambda k, c, r, s: get(find(k, "Deployment", "collector"), "spec.template.spec.securityContext").update(fsGroup=10001),
        "collector killed at once": lambda k, c, r, s: get(find(k, "Deployment", "collector"), "spec.template.spec").update(terminationGracePeriodSeconds=0),
    }
    # The systemd unit's, on its {section: {key: [values]}}.
    def exec_start(u, f):
        u["Service"]["ExecStart"] = [f(u["Service"]["ExecStart"][-1])]
    unit_breakages = {
        "unit without --under": lambda u: exec_start(u, lambda x: re.sub(r"--under[= ]\S+", "", x)),
        "unit not running tessera collect": lambda u: exec_start(u, lambda x: x.replace(" collect", " watch")),
        "unit writes beside the share": lambda u: u["Service"].update(ReadWritePaths=["/srv/frames"]),
        "unit not bound to the share's mount": lambda u: u["Unit"].pop("RequiresMountsFor"),
        "unit without the mount check": lambda u: u["Service"].pop("ExecStartPre"),
        "unit file system writable": lambda u: u["Service"].update(ProtectSystem=["full"]),
        "unit killed before a frame is written": lambda u: u["Service"].update(TimeoutStopSec=["5s"]),
        "unit runs as root": lambda u: u["Service"].update(User=["root"]),
        "unit not restarted": lambda u: u["Service"].update(Restart=["on-failure"]),
        "unit needs its environment file": lambda u: u["Service"].update(EnvironmentFile=["/etc/tessera/collect.env"]),
        "unit before the network": lambda u: u["Unit"].update(After=["remote-fs.target"]),
    }
    base = check_all(k8s, compose, root_compose, stages, unit)
    if base:
        print("self-test: the real files already have problems:\n  " + "\n  ".join(base))
        return 1
    failed = 0
    for what, breakage in breakages.items():
        k, c, r, s = copy.deepcopy(k8s), copy.deepcopy(compose), copy.deepcopy(root_compose), copy.deepcopy(stages)
        breakage(k, c, r, s)
        errs = check_all(k, c, r, s, unit)
        print(f"self-test: {what}: {'caught: ' + errs[0] if errs else 'NOT CAUGHT'}")
        failed += not errs
    for what, breakage in unit_breakages.items():
        u = copy.deepcopy(unit)
        breakage(u)
        errs = check_all(k8s, compose, root_compose, stages, u)
        print(f"self-test: {what}: {'caught: ' + errs[0] if errs else 'NOT CAUGHT'}")
        failed += not errs
    return 1 if failed else 0


def main(argv):
    args = [a for a in argv[1:] if not a.startswith("--")]
    root = args[0] if args else os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
    try:
        k8s = load_k8s(root)
        METRICS.update(exported_metrics(root))
        compose = load_yaml_docs(os.path.join(root, "docker", "compose.yaml"))[0]
        root_compose = load_yaml_docs(os.path.join(root, "compose.yaml"))[0]
        stages = dockerfile_stages(root)
        unit = load_unit(os.path.join(root, "docker", "systemd", "tessera-collect.service"))
    except (OSError, yaml.YAMLError) as e:
        print(f"validate_manifests: {e}", file=sys.stderr)
        return 1
    if "--self-test" in argv:
        return self_test(k8s, compose, root_compose, stages, unit)
    errs = check_all(k8s, compose, root_compose, stages, unit)
    for e in errs:
        print(e, file=sys.stderr)
    ndocs = sum(len(d) for d in k8s.values())
    print(f"validate_manifests: {ndocs} Kubernetes documents in {len(k8s)} files, docker/compose.yaml, "
          f"compose.yaml, docker/Dockerfile ({len(stages)} stages), docker/systemd/tessera-collect.service: "
          + ("ok" if not errs else f"{len(errs)} problem(s)"))
    return 1 if errs else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
