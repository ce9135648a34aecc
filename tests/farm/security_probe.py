#!/usr/bin/python3
"""Bad input a hostile peer could send, from an independent client (Python + grpcio).

Usage: security_probe.py HOST:PORT PROTO_DIR TMP_DIR CHECK...
Checks (each prints "ok CHECK" or raises):
  health          grpc.health.v1 Check answers SERVING without any token
  message-size    a 3 MiB request is refused with RESOURCE_EXHAUSTED (server: --max-message-bytes 2 MiB)
  bundle-paths    bundles with '..', absolute, duplicate and file-and-directory entries: INVALID_ARGUMENT
  mesh-escape     a scene whose mesh is outside its bundle ('../..', absolute): INVALID_ARGUMENT
  token-roles     the worker token does not grant ClientService calls, nor the client token
                  WorkerService calls: UNAUTHENTICATED (env PROBE_WORKER_TOKEN, PROBE_CLIENT_TOKEN)
  huge-job-id     a 1 MiB job id in GetJob, CancelJob, AckFrame and SetJobPriority: INVALID_ARGUMENT
                  naming the field and its bound, the id not echoed
  stray-results   a worker session that sends one TileResults of 5,000 results for leases never
                  issued, of a job that does not exist (4 KiB job ids), then leaves
  upload-stall    four uploads send 1 MiB and stall (server: --max-concurrent-uploads 4 and a short
                  --upload-idle-seconds): each ends DEADLINE_EXCEEDED naming the flag. Prints
                  "stalled uploads ended" (or "stalled uploads still open") and keeps any stream
                  still open until TMP_DIR/upload-stall.done exists, so that the test can try an
                  upload of its own meanwhile
"""
import hashlib
import os
import sys
import time

import tessera_stubs


def main():
    address, proto_dir, tmp = sys.argv[1:4]
    checks = sys.argv[4:]
    import grpc
    cs, cs_grpc, common = tessera_stubs.generate(proto_dir, tmp)

    channel = grpc.insecure_channel(address)
    stub = cs_grpc.ClientServiceStub(channel)

    def expect(code, fn, what, needle=None, forbid=None):
        try:
            fn()
        except grpc.RpcError as e:
            assert e.code() == code, f"{what}: expected {code}, got {e.code()}: {e.details()}"
            if needle:
                assert needle in e.details(), f"{what}: '{needle}' not in '{e.details()}'"
            if forbid:
                assert forbid not in e.details(), f"{what}: '{forbid}' leaked into '{e.details()}'"
            print(f"  {what}: {e.code().name}: {e.details()}")
            return
        raise AssertionError(f"{what}: accepted")

    def upload(bundle):
        data = bundle.SerializeToString()
        sha = hashlib.sha256(data).hexdigest()
        stub.UploadBundle(iter([common.BundleChunk(sha256=sha, data=data)]), timeout=10)
        return sha

    for check in checks:
        if check == "health":
            call = channel.unary_unary("/grpc.health.v1.Health/Check",
                                       request_serializer=lambda b: b, response_deserializer=lambda b: b)
            assert call(b"", timeout=10) == b"\x08\x01", "health: not SERVING"  # status: SERVING
        elif check == "message-size":
            expect(grpc.StatusCode.RESOURCE_EXHAUSTED,
                   lambda: stub.HasBundle(cs.HasBundleRequest(sha256="a" * (3 << 20)), timeout=10),
                   "3 MiB HasBundle request")
        elif check == "bundle-paths":
            scene = b'{"camera": {}, "objects": []}'
            bad = {
                "dotdot": common.Bundle(scene_file="s.json", files=[
                    common.BundleFile(path="s.json", content=scene), common.BundleFile(path="../evil", content=b"x")]),
                "absolute": common.Bundle(scene_file="/tmp/s.json", files=[
                    common.BundleFile(path="/tmp/s.json", content=scene)]),
                "inner-dotdot": common.Bundle(scene_file="a/../s.json", files=[
                    common.BundleFile(path="a/../s.json", content=scene)]),
                "duplicate": common.Bundle(scene_file="s.json", files=[
                    common.BundleFile(path="s.json", content=scene), common.BundleFile(path="s.json", content=b"{}")]),
                "file-and-dir": common.Bundle(scene_file="s.json", files=[
                    common.BundleFile(path="s.json", content=scene), common.BundleFile(path="s.json/x", content=b"")]),
            }
            for name, b in bad.items():
                expect(grpc.StatusCode.INVALID_ARGUMENT, lambda: upload(b), f"bundle {name}", "bundle refused")
        elif check == "mesh-escape":
            for target in ("../../../../../../../../etc/passwd", "/etc/passwd"):
                scene = ('{"camera": {"position": [0, 0, 5], "look_at": [0, 0, 0], "up": [0, 1, 0], "vfov_deg": 40},'
                         ' "objects": [{"type": "mesh", "file": "%s"}]}' % target).encode()
                sha = upload(common.Bundle(scene_file="s.json", files=[common.BundleFile(path="s.json", content=scene)]))
                expect(grpc.StatusCode.INVALID_ARGUMENT,
                       lambda: stub.SubmitJob(cs.SubmitJobRequest(bundle_sha256=sha), timeout=10),
                       f"mesh {target}", "outside the scene bundle", forbid=tmp)
            # A mesh inside the bundle whose material library is not: assimp's own file access
            # is confined too. The message names files as the bundle does (no coordinator paths).
            obj = b"mtllib ../../../../../../../../etc/passwd\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"
            scene = (b'{"camera": {"position": [0, 0, 5], "look_at": [0, 0, 0], "up": [0, 1, 0], "vfov_deg": 40},'
                     b' "objects": [{"type": "mesh", "file": "m.obj"}]}')
            sha = upload(common.Bundle(scene_file="s.json", files=[common.BundleFile(path="s.json", content=scene),
                                                                    common.BundleFile(path="m.obj", content=obj)]))
            expect(grpc.StatusCode.INVALID_ARGUMENT,
                   lambda: stub.SubmitJob(cs.SubmitJobRequest(bundle_sha256=sha), timeout=10),
                   "mtllib outside the bundle", "invalid scene: s.json: objects[0].file: m.obj: refers to", forbid=tmp)
        elif check == "instance-bomb":
            # an instance bomb, once flattened before the primitive limit was checked: a glTF
            # of ~0.8 MB whose 1,000 nodes all instance one 20,000-triangle mesh (its buffer in a
            # side .bin): 20 M triangles once flattened. The coordinator (--max-primitives 100000)
            # must refuse it before flattening; the test reads its peak memory afterwards.
            import json, struct
            tris = 20000
            verts = []
            for t in range(tris):
                x, y = (t % 200) * 0.01, (t // 200) * 0.01
                verts += [x, y, 0.0, x + 0.01, y, 0.0, x, y + 0.01, 0.0]
            buf = struct.pack("<%df" % len(verts), *verts)
            gltf = {"asset": {"version": "2.0"}, "scene": 0,
                    "scenes": [{"nodes": list(range(1000))}],
                    "nodes": [{"mesh": 0, "translation": [i * 0.001, 0, 0]} for i in range(1000)],
                    "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
                    "buffers": [{"uri": "m.bin", "byteLength": len(buf)}],
                    "bufferViews": [{"buffer": 0, "byteLength": len(buf)}],
                    "accessors": [{"bufferView": 0, "componentType": 5126, "count": tris * 3, "type": "VEC3",
                                   "min": [0, 0, 0], "max": [2.01, 1.01, 0]}]}
            scene = (b'{"camera": {"position": [0, 0, 5], "look_at": [0, 0, 0], "up": [0, 1, 0], "vfov_deg": 40},'
                     b' "objects": [{"type": "mesh", "file": "m.gltf"}]}')
            sha = upload(common.Bundle(scene_file="s.json", files=[
                common.BundleFile(path="s.json", content=scene),
                common.BundleFile(path="m.gltf", content=json.dumps(gltf).encode()),
                common.BundleFile(path="m.bin", content=buf)]))
            expect(grpc.StatusCode.RESOURCE_EXHAUSTED,
                   lambda: stub.SubmitJob(cs.SubmitJobRequest(bundle_sha256=sha), timeout=120),
                   "1,000 instances of a 20,000-triangle mesh", "limit max_primitives")
        elif check == "upload-flood":
            # a flood of uploads, once buffered whole in memory: four concurrent 100 MB uploads
            # announcing a wrong hash (the server runs with --max-concurrent-uploads 4): each
            # refused at its end for the hash, a fifth at the same time refused at once; the test
            # reads the peak memory after.
            import threading
            chunk = b"\x5a" * (1 << 20)
            release = threading.Event()
            results = {}

            def flood(i, mib):
                def chunks():
                    yield common.BundleChunk(sha256="0" * 64, data=chunk)
                    release.wait(60)  # hold the slot until every upload has started
                    for _ in range(mib - 1):
                        yield common.BundleChunk(data=chunk)
                try:
                    stub.UploadBundle(chunks(), timeout=300)
                    results[i] = "accepted"
                except grpc.RpcError as e:
                    results[i] = f"{e.code().name}: {e.details()}"

            threads = [threading.Thread(target=flood, args=(i, 100)) for i in range(4)]
            for t in threads: t.start()
            time.sleep(2)  # the four are in progress (each sent its first chunk)
            fifth = threading.Thread(target=flood, args=(4, 1))
            fifth.start(); fifth.join(60)
            release.set()
            for t in threads: t.join(300)
            print("  results:", results)
            assert results[4].startswith("RESOURCE_EXHAUSTED") and "--max-concurrent-uploads" in results[4], results[4]
            for i in range(4):
                assert results[i].startswith("INVALID_ARGUMENT") and "not to the announced" in results[i], results[i]
        elif check == "huge-job-id":
            huge = "z" * (1 << 20)
            for name, call in (("GetJob", lambda: stub.GetJob(cs.GetJobRequest(job_id=huge), timeout=10)),
                               ("CancelJob", lambda: stub.CancelJob(cs.CancelJobRequest(job_id=huge), timeout=10)),
                               ("AckFrame", lambda: stub.AckFrame(cs.AckFrameRequest(job_id=huge), timeout=10)),
                               ("SetJobPriority",
                                lambda: stub.SetJobPriority(cs.SetJobPriorityRequest(job_id=huge), timeout=10))):
                expect(grpc.StatusCode.INVALID_ARGUMENT, call, f"{name} with a 1 MiB job id",
                       "job_id: 1048576 bytes, at most 64", forbid="zzzz")
        elif check == "stray-results":
            from tessera.v1 import worker_service_pb2 as ws
            from tessera.v1 import worker_service_pb2_grpc as ws_grpc
            tile = dict(job_id="j" * 4096, frame=0)
            batch = ws.TileResults(results=[ws.TileResult(lease_id=(1 << 40) + i,
                                                          tile=common.TileData(tile_index=i, **tile))
                                            for i in range(5000)])

            def session():
                yield ws.WorkerMessage(register=ws.Register(name="stray", threads=1))
                yield ws.WorkerMessage(results=batch)
                time.sleep(1)  # the session stays while the coordinator takes the burst

            try:
                for _ in ws_grpc.WorkerServiceStub(channel).Connect(session(), timeout=30):
                    pass
            except grpc.RpcError as e:
                print(f"  session ended: {e.code().name}: {e.details()[:200]}")
        elif check == "upload-stall":
            import threading
            release = threading.Event()
            results = {}

            def stall(i):
                def chunks():
                    yield common.BundleChunk(sha256="0" * 64, data=b"\x5a" * (1 << 20))
                    release.wait(300)  # sends nothing more: the server must end it
                try:
                    stub.UploadBundle(chunks(), timeout=300)
                    results[i] = "accepted"
                except grpc.RpcError as e:
                    results[i] = f"{e.code().name}: {e.details()}"

            threads = [threading.Thread(target=stall, args=(i,), daemon=True) for i in range(4)]
            for t in threads: t.start()
            deadline = time.time() + 30  # the server's idle timeout ends them long before this
            for t in threads: t.join(max(0.0, deadline - time.time()))
            ended = all(i in results for i in range(4))
            print("  results:", results)
            print("stalled uploads ended" if ended else "stalled uploads still open", flush=True)
            done = os.path.join(tmp, "upload-stall.done")
            for _ in range(3000):
                if os.path.exists(done): break
                time.sleep(0.1)
            release.set()
            assert ended, results
            for i in range(4):
                assert results[i].startswith("DEADLINE_EXCEEDED") and "--upload-idle-seconds" in results[i], results[i]
        elif check == "token-roles":
            md = [("authorization", "Bearer " + os.environ["PROBE_WORKER_TOKEN"])]
            expect(grpc.StatusCode.UNAUTHENTICATED,
                   lambda: stub.ListJobs(cs.ListJobsRequest(), timeout=10, metadata=md),
                   "ListJobs with the worker token", "invalid client token")
            expect(grpc.StatusCode.UNAUTHENTICATED,
                   lambda: stub.ListJobs(cs.ListJobsRequest(), timeout=10,
                                         metadata=[("authorization", "Basic " + os.environ["PROBE_WORKER_TOKEN"])]),
                   "ListJobs with a non-Bearer authorization")
            # ... and the client token does not grant worker calls (bundle fetch, session).
            from tessera.v1 import worker_service_pb2 as ws
            from tessera.v1 import worker_service_pb2_grpc as ws_grpc
            wstub = ws_grpc.WorkerServiceStub(channel)
            cmd = [("authorization", "Bearer " + os.environ["PROBE_CLIENT_TOKEN"])]
            expect(grpc.StatusCode.UNAUTHENTICATED,
                   lambda: list(wstub.FetchBundle(ws.FetchBundleRequest(sha256="0" * 64), timeout=10, metadata=cmd)),
                   "FetchBundle with the client token", "invalid worker token")
            expect(grpc.StatusCode.UNAUTHENTICATED,
                   lambda: list(wstub.Connect(iter([ws.WorkerMessage()]), timeout=10, metadata=cmd)),
                   "Connect with the client token", "invalid worker token")
            # Ray servers: announcing takes the worker token, listing the client token.
            expect(grpc.StatusCode.UNAUTHENTICATED,
                   lambda: wstub.AnnounceRayServer(ws.RayServerAnnouncement(
                       server=common.RayServerDescription(server_id="x", address="127.0.0.1:1"), period_ms=1000),
                       timeout=10, metadata=cmd),
                   "AnnounceRayServer with the client token", "invalid worker token")
            expect(grpc.StatusCode.UNAUTHENTICATED,
                   lambda: stub.ListRayServers(cs.ListRayServersRequest(), timeout=10, metadata=md),
                   "ListRayServers with the worker token", "invalid client token")
        else:
            raise SystemExit("unknown check " + check)
        print("ok", check)
    return 0


if __name__ == "__main__":
    sys.exit(main())
