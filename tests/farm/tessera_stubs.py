"""Python stubs for tessera.v1, generated from the .proto files alone (grpc_tools.protoc), so the
Python test clients are independent of the C++ code generation."""
import os
import subprocess
import sys


def generate(proto_dir, tmp):
    """Generates the stubs under tmp/pygen and returns (client_service_pb2,
    client_service_pb2_grpc, common_pb2)."""
    gen = os.path.join(tmp, "pygen")
    os.makedirs(gen, exist_ok=True)
    protos = [os.path.join(proto_dir, "tessera", "v1", n)
              for n in ("common.proto", "client_service.proto", "worker_service.proto")]
    subprocess.check_call([sys.executable, "-m", "grpc_tools.protoc", "-I", proto_dir,
                           "--python_out", gen, "--grpc_python_out", gen] + protos)
    sys.path.insert(0, gen)
    from tessera.v1 import client_service_pb2, client_service_pb2_grpc, common_pb2
    return client_service_pb2, client_service_pb2_grpc, common_pb2
