# SPDX-License-Identifier: Apache-2.0
"""How things go wrong: a cancelled job, a wrong token, a missing file, a scene the coordinator
refuses, arguments out of range. Each says what is wrong, by the farm's code or by name."""

from __future__ import annotations

import os

import grpc
import numpy as np
import pytest

import harness
import scenes
import tessera


def test_a_cancelled_job_raises_job_cancelled_after_its_finished_frames(make_farm, scratch):
    farm = make_farm()
    # A slow worker (60 ms a tile, 12 tiles a frame): the job is still running when the consumer
    # cancels it after the first frame.
    farm.add_worker("slow", extra=["--test-delay-ms", "60"])
    farm.wait_for_workers(["slow"])
    anim = scenes.animated_json(os.path.join(scratch, "anim.json"), frames=4)
    got = []
    with tessera.Farm(farm.address) as f:
        job = f.submit(anim, width=64, height=48, spp=4, tile_size=16)
        with pytest.raises(tessera.JobCancelled) as raised:
            for frame in job.frames():
                got.append(frame)
                if len(got) == 1:
                    assert job.cancel().state == "cancelled"
        status = job.status()
    assert isinstance(raised.value, tessera.FarmError)
    assert raised.value.job_id == job.id and "cancelled" in str(raised.value)
    assert status.state == "cancelled" and status.tiles_done < status.tiles_total
    assert [g.index for g in got] == sorted(status.frames_done)[:len(got)] and got[0].index == 0
    want = harness.render(anim, 0, scratch, "--width", "64", "--height", "48", "--spp", "4")
    np.testing.assert_array_equal(harness.bits(got[0].rgb[:, :, 0]), harness.bits(want["R"]))


def test_a_wrong_or_missing_token_is_unauthenticated(make_farm, scratch):
    token_file = scenes.write(os.path.join(scratch, "client.token"), "  s3cret-token\n")
    farm = make_farm("--client-token-file", token_file)
    bunny = harness.scene("scenes/bunny.json")
    for token in ("wrong", None):
        with tessera.Farm(farm.address, token=token) as f:
            with pytest.raises(tessera.FarmError) as raised:
                f.workers()
            assert raised.value.code == grpc.StatusCode.UNAUTHENTICATED
            assert type(raised.value) is tessera.Unauthenticated
            assert "UNAUTHENTICATED" in str(raised.value) and raised.value.message in str(raised.value)
            with pytest.raises(tessera.FarmError) as raised:
                f.submit(bunny, spp=1, width=8, height=8)  # refused at HasBundle, before any upload
            assert raised.value.code == grpc.StatusCode.UNAUTHENTICATED
    # The CLI's rule for the file (surrounding blanks dropped) gives the token that works.
    assert tessera.read_token_file(token_file) == "s3cret-token"
    with tessera.Farm(farm.address, token=tessera.read_token_file(token_file)) as f:
        assert f.workers() == [] and f.jobs() == []
    assert "no jobs on" in harness.run_cli("status", "--coordinator", farm.address, "--token-file", token_file).stdout


def test_read_token_file_follows_the_cli_rules(scratch):
    assert tessera.read_token_file(scenes.write(os.path.join(scratch, "t1"), "\t abc def \r\n")) == "abc def"
    with pytest.raises(ValueError, match="is empty"):
        tessera.read_token_file(scenes.write(os.path.join(scratch, "t2"), " \n\t"))
    with pytest.raises(FileNotFoundError) as raised:
        tessera.read_token_file(os.path.join(scratch, "nope"))
    assert raised.value.filename == os.path.join(scratch, "nope")


def test_missing_scene_and_mesh_files_are_named(bare_farm, scratch):
    with tessera.Farm(bare_farm.address) as f:
        missing = os.path.join(scratch, "no-such-scene.json")
        with pytest.raises(FileNotFoundError) as raised:
            f.submit(missing)
        assert raised.value.filename == missing and missing in str(raised.value)
        scene = scenes.json_with(os.path.join(scratch, "s.json"),
                                 objects=[{"type": "mesh", "file": "models/gone.ply", "material": "grey"}])
        with pytest.raises(FileNotFoundError) as raised:
            f.submit(scene)
        assert "gone.ply" in str(raised.value)
        with pytest.raises(FileNotFoundError):
            f.rays(missing, np.zeros((1, 3)), np.array([[0, 0, 1.0]]), server="127.0.0.1:1")
        # Nothing reached the coordinator.
        assert f.jobs() == []


def test_a_scene_the_coordinator_refuses_is_invalid_argument_with_its_message(bare_farm, scratch):
    bad = scenes.json_with(os.path.join(scratch, "bad.json"),
                           objects=[{"type": "sphere", "center": [0, 0, 0], "radius": -1, "material": "grey"}])
    with tessera.Farm(bare_farm.address) as f:
        with pytest.raises(tessera.FarmError) as raised:
            f.submit(bad)
    e = raised.value
    assert e.code == grpc.StatusCode.INVALID_ARGUMENT and type(e) is tessera.InvalidArgument
    assert e.message.startswith("invalid scene: bad.json: ") and "radius" in e.message
    # The parser's words, as `tessera render` reports them for the same file.
    r = harness.run_cli("render", bad, "-o", os.path.join(scratch, "x.exr"), check=False)
    assert r.returncode == 2
    assert e.message.split("bad.json: ", 1)[1] in r.stderr


def test_arguments_are_checked_here_and_named(bare_farm, scratch):
    anim = scenes.animated_json(os.path.join(scratch, "anim.json"), frames=3)
    glb = harness.scene("tests/data/gltf/whitted_a.glb")
    with tessera.Farm(bare_farm.address) as f:
        cases = [
            (dict(spp=4, target_rmse=0.01), "spp and target_rmse conflict"),
            (dict(target_rmse=0.01, block_rmse=0.01), "target_rmse and block_rmse conflict"),
            (dict(target_rmse=0.0), "target_rmse: must be a finite number > 0"),
            (dict(target_rmse=float("nan")), "target_rmse: must be a finite number > 0"),
            (dict(width=0), r"width: must be in \[1, 16384\], got 0"),
            (dict(height=20000), r"height: must be in \[1, 16384\], got 20000"),
            (dict(spp=70000), r"spp: must be in \[1, 65536\], got 70000"),
            (dict(spp=2.5), "spp: must be an integer"),
            (dict(min_spp=1, target_rmse=0.1), r"min_spp: must be in \[2, 65536\]"),
            (dict(min_spp=64, max_spp=32, target_rmse=0.1), r"min_spp \(64\) must not exceed max_spp \(32\)"),
            (dict(frames="2-5"), "frames 2-5: the scene has frames 0-2"),
            (dict(frames=3), "frames 3-3: the scene has frames 0-2"),
            (dict(frames="1-x"), "frames: expected A or A-B, got '1-x'"),
            (dict(frames=range(2, 0)), "frames: a range must be non-empty"),
            (dict(camera="Camera"), "camera, scene_index and fps apply to glTF scenes"),
            (dict(sampler="halton"), "sampler: must be one of"),
            (dict(tile_size=2), r"tile_size: must be in \[4, 256\]"),
        ]
        for kwargs, message in cases:
            with pytest.raises(ValueError, match=message):
                f.submit(anim, **kwargs)
        with pytest.raises(ValueError, match=r"fps: must be in \(0, 1000\]"):
            f.submit(glb, fps=0)
        with pytest.raises(ValueError, match=r"scene_index: must be in \[0"):
            f.submit(glb, scene_index=-1)
        assert f.jobs() == []  # nothing was submitted
        # Valid ones go through, as the CLI's flags would.
        ok = f.submit(anim, frames=range(1, 3), target_rmse=0.05, min_spp=4, max_spp=16, sampler="stratified")
        st = ok.status()
        assert (st.first_frame, st.last_frame) == (1, 2)
        assert st.target_rmse == 0.05 and st.overrides["sampler"] == "sobol" and st.overrides["max_spp"] == 16
        # What only the coordinator can check comes back from it, e.g. a glTF's frame count.
        with pytest.raises(tessera.FarmError) as raised:
            f.submit(glb, frames="0-500")
        assert raised.value.code == grpc.StatusCode.INVALID_ARGUMENT and "the scene has frames" in raised.value.message
