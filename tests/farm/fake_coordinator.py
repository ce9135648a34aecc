#!/usr/bin/python3
"""A lying coordinator, built from the .proto files alone: it says job "liar" is done and
sends frame 0 of it with a tile missing (frame_done after 1 of its 2 tiles), the way a
coordinator serving a damaged store once did. The client must neither write that frame nor
acknowledge it, and must not exit 0.

Usage: fake_coordinator.py PROTO_DIR TMP_DIR
Prints "listening on 127.0.0.1:PORT", then one line "ACK job frame" per AckFrame received.
"""
import struct
import sys
import time
from concurrent import futures

import tessera_stubs


def main():
    proto_dir, tmp = sys.argv[1:3]
    import grpc
    cs, cs_grpc, common = tessera_stubs.generate(proto_dir, tmp)

    def status(state):
        return cs.JobStatus(job_id="liar", name="liar", state=state, first_frame=0, last_frame=0, width=8,
                            height=4, spp=1, tile_size=4, tiles_per_frame=2, tiles_total=2, tiles_done=2,
                            frames_done=[0])

    class Liar(cs_grpc.ClientServiceServicer):
        def GetJob(self, request, context):
            return status(cs.JOB_STATE_DONE)

        def WatchJob(self, request, context):
            yield cs.WatchJobEvent(status=status(cs.JOB_STATE_DONE))
            # Tile 0 (x 0-3) only; tile 1 (x 4-7) never comes.
            rgb = struct.pack("<48f", *([0.5] * 48))
            var = struct.pack("<16f", *([0.0] * 16))
            yield cs.WatchJobEvent(tile=common.TileData(job_id="liar", frame=0, tile_index=0,
                                                        rect=common.TileRect(x0=0, y0=0, width=4, height=4),
                                                        rgb=rgb, variance=var, worker="fake"))
            yield cs.WatchJobEvent(frame_done=0)
            yield cs.WatchJobEvent(status=status(cs.JOB_STATE_DONE))

        def AckFrame(self, request, context):
            print(f"ACK {request.job_id} {request.frame}", flush=True)
            return cs.AckFrameResponse()

    server = grpc.server(futures.ThreadPoolExecutor(max_workers=4))
    cs_grpc.add_ClientServiceServicer_to_server(Liar(), server)
    port = server.add_insecure_port("127.0.0.1:0")
    server.start()
    print(f"listening on 127.0.0.1:{port}", flush=True)
    while True:
        time.sleep(3600)


if __name__ == "__main__":
    main()
