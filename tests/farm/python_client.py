#!/usr/bin/python3
"""An independent Tessera farm client: Python + grpcio, stubs generated from proto/ at run time.

Usage: python_client.py HOST:PORT PROTO_DIR SCENE_JSON TMP_DIR

Lists the workers, uploads a one-file scene bundle (built here, hashed here), submits a
one-frame job, watches it to the end and checks every tile arrived with the right size.
Proves the .proto files are a usable contract on their own.
"""
import hashlib
import os
import struct
import sys

import tessera_stubs


def main():
    address, proto_dir, scene_path, tmp = sys.argv[1:5]
    import grpc
    cs, cs_grpc, common = tessera_stubs.generate(proto_dir, tmp)

    channel = grpc.insecure_channel(address)
    stub = cs_grpc.ClientServiceStub(channel)

    workers = stub.ListWorkers(cs.ListWorkersRequest(), timeout=10).workers
    print("workers:", ", ".join(f"{w.name} ({w.threads} threads, {w.embree_isa})" for w in workers))
    assert len(workers) >= 1, "expected a worker"

    with open(scene_path, "rb") as f:
        scene_bytes = f.read()
    name = os.path.basename(scene_path)
    bundle = common.Bundle(scene_file=name, files=[common.BundleFile(path=name, content=scene_bytes)])
    data = bundle.SerializeToString()
    sha = hashlib.sha256(data).hexdigest()
    if not stub.HasBundle(cs.HasBundleRequest(sha256=sha), timeout=10).present:
        chunks = [common.BundleChunk(sha256=sha, data=data[i:i + (1 << 20)])
                  for i in range(0, max(len(data), 1), 1 << 20)]
        resp = stub.UploadBundle(iter(chunks), timeout=60)
        print("uploaded", resp.sha256[:12], resp.size, "bytes")

    # A wrong hash must be refused with INVALID_ARGUMENT.
    try:
        stub.UploadBundle(iter([common.BundleChunk(sha256="0" * 64, data=data)]), timeout=10)
        raise AssertionError("a bundle with a wrong hash was accepted")
    except grpc.RpcError as e:
        assert e.code() == grpc.StatusCode.INVALID_ARGUMENT, e

    job = stub.SubmitJob(cs.SubmitJobRequest(
        bundle_sha256=sha, first_frame=1, last_frame=1, tile_size=32, name="python",
        overrides=common.ImageOverrides(width=64, height=48, spp=2)), timeout=10)
    print("submitted job", job.job_id, job.tiles_total, "tiles")
    assert job.tiles_total == 2 * 2

    tiles = 0
    final = None
    for ev in stub.WatchJob(cs.WatchJobRequest(job_id=job.job_id), timeout=120):
        kind = ev.WhichOneof("event")
        if kind == "tile":
            t = ev.tile
            n = t.rect.width * t.rect.height
            # float32 pixels; the variance as bfloat16; a fixed-spp job's counts said once a tile.
            assert len(t.rgb) == 12 * n and len(t.variance_bf16) == 2 * n and not t.variance, (len(t.variance_bf16), len(t.variance))
            assert not t.spp and t.uniform_spp == 2, (len(t.spp), t.uniform_spp)
            var = struct.unpack("<%dH" % n, t.variance_bf16)
            assert all((v & 0x7f80) != 0x7f80 for v in var), "a variance is not finite"
            rgb = struct.unpack("<%df" % (3 * n), t.rgb)  # little-endian float32, as documented
            assert all(v == v for v in rgb), "NaN in a tile"
            tiles += 1
        elif kind == "frame_done":
            stub.AckFrame(cs.AckFrameRequest(job_id=job.job_id, frame=ev.frame_done), timeout=10)
        elif kind == "status":
            final = ev.status
    assert final is not None and final.state == cs.JOB_STATE_DONE, final
    assert tiles == 4, tiles
    print("job done:", tiles, "tiles received")

    try:
        stub.GetJob(cs.GetJobRequest(job_id="nope"), timeout=10)
        raise AssertionError("unknown job accepted")
    except grpc.RpcError as e:
        assert e.code() == grpc.StatusCode.NOT_FOUND, e
    return 0


if __name__ == "__main__":
    sys.exit(main())
