#!/usr/bin/python3
"""A Python client of tessera.v1.RayService, built from proto/tessera/v1/ray_service.proto alone.

Usage: rays_client.py RAYS_HOST:PORT PROTO_DIR BUNDLE_SHA256 [TOKEN]

Needs grpcio, grpcio-tools and numpy (Debian: python3-grpcio python3-grpc-tools python3-numpy).
The bundle must be on the coordinator already (`tessera rays SCENE ... --server` uploads it, and
so does `tessera submit`). Prints the scene's objects, a few nearest hits, the same rays asking
for t alone, an occlusion query, a streamed batch and one refused batch. docs/rays.md walks through it; the tests run it.
"""
import os
import subprocess
import sys
import tempfile

import numpy as np


def stubs(proto_dir):
    """ray_service_pb2 and ray_service_pb2_grpc, generated at run time from the .proto."""
    out = tempfile.mkdtemp(prefix="tessera-rays-py-")
    proto = os.path.join(proto_dir, "tessera", "v1", "ray_service.proto")
    subprocess.check_call([sys.executable, "-m", "grpc_tools.protoc", "-I", proto_dir,
                           "--python_out", out, "--grpc_python_out", out, proto])
    sys.path.insert(0, out)
    from tessera.v1 import ray_service_pb2, ray_service_pb2_grpc
    return ray_service_pb2, ray_service_pb2_grpc


def request(pb, scene, origins, directions, t_max=None, occlusion=False, fields=()):
    """Packed arrays: numpy (n, 3) float64 origins and directions, flattened. `fields`: the
    response's field mask (pb.HIT_FIELD_T, ...); empty: every field."""
    req = pb.TraceRequest(occlusion=occlusion, fields=fields,
                          origins=np.asarray(origins, np.float64).ravel().tolist(),
                          directions=np.asarray(directions, np.float64).ravel().tolist())
    if scene is not None:  # on a stream, only the first request needs it
        req.scene.CopyFrom(scene)
    if t_max is not None:
        req.t_max.extend(float(x) for x in t_max)
    return req


def main():
    address, proto_dir, sha = sys.argv[1:4]
    token = sys.argv[4] if len(sys.argv) > 4 else ""
    import grpc
    pb, pb_grpc = stubs(proto_dir)
    stub = pb_grpc.RayServiceStub(grpc.insecure_channel(address))
    md = [("authorization", "Bearer " + token)] if token else None
    scene = pb.SceneRef(bundle_sha256=sha, frame=0)

    info = stub.DescribeScene(scene, timeout=60, metadata=md)
    print("objects:", ", ".join(f"{n} ({k})" for n, k in zip(info.objects, info.object_kinds)))
    print("embree:", info.embree_isa, "max batch:", info.max_batch_rays)

    # Nearest hits: the answer's arrays are index-aligned with the rays.
    o = [[0, 0, 0], [0, 0, 0], [0, 0, 0]]
    d = [[0, 0, 1], [0, -1, 0], [0, 1, 0]]
    r = stub.Trace(request(pb, scene, o, d), timeout=30, metadata=md)
    hit = np.frombuffer(r.hit, np.uint8)
    t = np.array(r.t, np.float32)
    p = np.array(r.points).reshape(-1, 3)
    n = np.array(r.normals, np.float32).reshape(-1, 3)
    for i in range(len(hit)):
        if hit[i]:
            print(f"ray {i}: hit {info.objects[r.objects[i]]} t={t[i]:.6g} p={p[i].tolist()} n={n[i].tolist()}")
        else:
            print(f"ray {i}: miss")

    # t alone (a lidar's question): `hit` and `t` come back, 5 bytes a ray instead of 73; the
    # arrays of fields not asked for are empty.
    r = stub.Trace(request(pb, scene, o, d, fields=[pb.HIT_FIELD_T]), timeout=30, metadata=md)
    print("t only:", np.frombuffer(r.hit, np.uint8).tolist(), np.array(r.t, np.float32).tolist(),
          "points sent:", len(r.points))

    # Line of sight: is anything within 7.5 units, within 20?
    r = stub.Trace(request(pb, scene, [[0, 0, 0]] * 2, [[0, 0, 1]] * 2, t_max=[7.5, 20], occlusion=True),
                   timeout=30, metadata=md)
    print("occluded:", np.frombuffer(r.hit, np.uint8).tolist())

    # A stream: several batches in flight on one call, answers in order.
    rng = np.random.default_rng(1)
    batches = [rng.normal(size=(1000, 3)) for _ in range(3)]
    reqs = (request(pb, scene if i == 0 else None, np.zeros((1000, 3)), b) for i, b in enumerate(batches))
    hits = [int(np.frombuffer(a.hit, np.uint8).sum()) for a in stub.TraceStream(reqs, timeout=60, metadata=md)]
    print("stream hits per batch:", hits)

    # Bad input is refused as a whole, naming the ray and the field.
    try:
        stub.Trace(request(pb, scene, [[0, 0, 0]] * 2, [[0, 0, 1], [0, 0, 0]]), timeout=30, metadata=md)
        print("bad batch: accepted?!")
        return 1
    except grpc.RpcError as e:
        print("bad batch refused:", e.code().name, e.details())
    return 0


if __name__ == "__main__":
    sys.exit(main())
