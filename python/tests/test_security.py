# SPDX-License-Identifier: Apache-2.0
"""TLS as the CLI speaks it: tls_ca checks the coordinator's certificate, tls_cert/tls_key answer a
coordinator that asks for client certificates, the token travels too; a plaintext client is told."""

from __future__ import annotations

import os
import subprocess

import grpc
import pytest

import harness
import scenes
import tessera


def make_pki(folder: str) -> dict[str, str]:
    """A CA, a server certificate for 127.0.0.1 and a client certificate (as tests/farm/test_pki.cpp)."""
    os.makedirs(folder, exist_ok=True)
    key = ["-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes"]

    def openssl(*args: str) -> None:
        subprocess.run(["openssl", *args], cwd=folder, check=True, capture_output=True)

    scenes.write(os.path.join(folder, "server.ext"), "subjectAltName=IP:127.0.0.1,DNS:localhost\n")
    scenes.write(os.path.join(folder, "client.ext"), "extendedKeyUsage=clientAuth\n")
    openssl("req", "-x509", *key, "-keyout", "ca.key", "-out", "ca.pem", "-days", "2", "-subj", "/CN=Tessera Test CA")
    for who, cn in (("server", "localhost"), ("client", "client-1")):
        openssl("req", *key, "-keyout", f"{who}.key", "-out", f"{who}.csr", "-subj", f"/CN={cn}")
        openssl("x509", "-req", "-in", f"{who}.csr", "-CA", "ca.pem", "-CAkey", "ca.key", "-CAcreateserial", "-days",
                "2", "-out", f"{who}.pem", "-extfile", f"{who}.ext")
    return {name: os.path.join(folder, name) for name in
            ("ca.pem", "server.pem", "server.key", "client.pem", "client.key")}


def test_mutual_tls_with_a_token_end_to_end(make_farm, scratch):
    pki = make_pki(os.path.join(scratch, "pki"))
    token = scenes.write(os.path.join(scratch, "token"), "tls-token\n")
    farm = make_farm("--tls-cert", pki["server.pem"], "--tls-key", pki["server.key"], "--tls-ca", pki["ca.pem"],
                     "--client-token-file", token)
    farm.add_worker("tls", extra=["--tls-ca", pki["ca.pem"], "--tls-cert", pki["client.pem"],
                                  "--tls-key", pki["client.key"]])
    whitted = harness.scene("scenes/whitted.json")
    with tessera.Farm(farm.address, token=tessera.read_token_file(token), tls_ca=pki["ca.pem"],
                      tls_cert=pki["client.pem"], tls_key=pki["client.key"]) as f:
        assert f.wait_ready(20)
        (frame,) = list(f.submit(whitted, width=32, height=24, spp=2).frames())
        assert frame.rgb.shape == (24, 32, 3) and [w.name for w in f.workers()] == ["tls"]
    # Plaintext at a TLS port: the connection fails, UNAVAILABLE.
    with tessera.Farm(farm.address, token="tls-token", timeout=5) as f:
        with pytest.raises(tessera.FarmError) as raised:
            f.jobs()
        assert raised.value.code == grpc.StatusCode.UNAVAILABLE
    # TLS without the client certificate the coordinator asks for: refused in the handshake.
    with tessera.Farm(farm.address, token="tls-token", tls_ca=pki["ca.pem"], timeout=5) as f:
        with pytest.raises(tessera.FarmError) as raised:
            f.jobs()
        assert raised.value.code == grpc.StatusCode.UNAVAILABLE
    with pytest.raises(ValueError, match="tls_cert and tls_key go together"):
        tessera.Farm(farm.address, tls_ca=pki["ca.pem"], tls_cert=pki["client.pem"])
    with pytest.raises(FileNotFoundError):
        tessera.Farm(farm.address, tls_ca=os.path.join(scratch, "missing.pem"))
