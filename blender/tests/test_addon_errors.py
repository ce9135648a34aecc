# SPDX-License-Identifier: Apache-2.0
"""Farm errors become Blender error reports with the farm's message, never a traceback
(run_blender_test.py --farm secure:token=1,max_spp=64,workers=0)."""

import os
import socket
import sys
import time

sys.path.insert(0, os.environ["TESSERA_TEST_LIB"])
import bpy  # noqa: E402

import blender_test_lib as T  # noqa: E402

addon = T.install_addon()
ADDR, TOKEN_FILE = T.farm("secure")
os.environ.pop("TESSERA_CLIENT_TOKEN", None)  # the package would take it when no token is given


def expect_error(address, token_file=None, spp=4, timeout=5.0, *needles):
    scene = T.build_scene()
    T.configure(scene, address, token_file=token_file, spp=spp, timeout=timeout)
    before = len(bpy.data.images)
    ok, err = T.render()
    print("report:", err)
    assert not ok and err, "the operator did not fail"
    assert err.startswith("Error: Tessera"), err
    assert "Traceback" not in err and "File \"" not in err, err
    for n in needles:
        assert n in err, f"{n!r} not in the report: {err}"
    assert len(bpy.data.images) == before, "an image was made for a failed job"
    assert not scene.tessera.last_job_id, scene.tessera.last_job_id
    return err


def test_wrong_address():
    # Nothing listens on port 1: refused at once.
    expect_error("127.0.0.1:1", None, 4, 5.0, "UNAVAILABLE", "127.0.0.1:1")


def test_unresponsive_coordinator():
    # A port that takes the connection and never says a word (a hung coordinator, a firewall
    # that black-holes): the call's deadline, the panel's Timeout, ends it.
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen(8)
        address = "127.0.0.1:%d" % s.getsockname()[1]
        t0 = time.monotonic()
        err = expect_error(address, None, 4, 1.5, address)
        took = time.monotonic() - t0
    assert "DEADLINE_EXCEEDED" in err or "UNAVAILABLE" in err, err
    assert took < 15, took


def test_wrong_token():
    wrong = os.path.join(T.TMP, "wrong.token")
    with open(wrong, "w") as f:
        f.write("not-the-token\n")
    expect_error(ADDR, wrong, 4, 5.0, "UNAUTHENTICATED", "invalid client token", "Token file")


def test_no_token():
    expect_error(ADDR, None, 4, 5.0, "UNAUTHENTICATED")


def test_missing_token_file():
    expect_error(ADDR, os.path.join(T.TMP, "no-such.token"), 4, 5.0, "no-such.token")


def test_refused_scene():
    # The right token, but more samples than this coordinator allows (--max-spp 64).
    expect_error(ADDR, TOKEN_FILE, 100, 5.0, "spp is 100", "--max-spp", "INVALID_ARGUMENT")


T.run_tests([
    ("wrong_address", test_wrong_address),
    ("unresponsive_coordinator", test_unresponsive_coordinator),
    ("wrong_token", test_wrong_token),
    ("no_token", test_no_token),
    ("missing_token_file", test_missing_token_file),
    ("refused_scene", test_refused_scene),
])
