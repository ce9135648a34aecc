# SPDX-License-Identifier: Apache-2.0
"""Job.frames() gives `tessera render`'s pixels bit for bit, its error layers too, and acknowledges
each frame only once the consumer has taken it."""

from __future__ import annotations

import os
import subprocess

import numpy as np

import harness
import scenes
import tessera

SIZE = ["--width", "64", "--height", "48", "--spp", "4"]


def assert_frame_is_render(frame: tessera.Frame, scene_path: str, scratch: str, error_channels: bool) -> None:
    """The frame equals `tessera render` of the same scene, frame and overrides, bit for bit."""
    want = harness.render(scene_path, frame.index, scratch, *SIZE, *(["--error-channels"] if error_channels else []))
    assert frame.rgb.dtype == np.float32 and frame.rgb.shape == (48, 64, 3)
    for i, c in enumerate("RGB"):
        np.testing.assert_array_equal(harness.bits(frame.rgb[:, :, i]), harness.bits(want[c]),
                                      err_msg=f"frame {frame.index} channel {c}")
    if error_channels:
        assert frame.error is not None and frame.spp is not None
        assert frame.error.dtype == np.float32 and frame.spp.dtype == np.uint32
        np.testing.assert_array_equal(harness.bits(frame.error), harness.bits(want["error.Y"]))
        np.testing.assert_array_equal(frame.spp.astype(np.float32), want["spp.Y"])
        assert set(np.unique(frame.spp)) == {4}
        assert float(frame.error.max()) > 0  # a real estimate, not zeros
    else:
        assert frame.error is None and frame.spp is None
        assert set(want) == {"R", "G", "B"}


def test_a_frame_is_tessera_render_bit_for_bit_with_its_error_channels(worker_farm, scratch):
    bunny = harness.scene("scenes/bunny.json")
    seen: list[tessera.Progress] = []
    with tessera.Farm(worker_farm.address) as farm:
        job = farm.submit(bunny, width=64, height=48, spp=4, tile_size=16)
        frames = list(job.frames(error_channels=True, progress=seen.append))
        status = job.status()
    assert [f.index for f in frames] == [0]
    assert_frame_is_render(frames[0], bunny, scratch, error_channels=True)
    # Progress came from the stream, tile by tile, and ended with the whole job.
    assert all(a.tiles_done <= b.tiles_done for a, b in zip(seen, seen[1:]))
    assert seen[0].tiles_done == 0 and any(0 < p.tiles_done for p in seen[:-1])
    assert seen[-1].state == "done" and seen[-1].tiles_done == seen[-1].tiles_total == 12
    assert seen[-1].frames_done == seen[-1].frames_total == 1
    assert seen[-1].estimated_rmse is not None and seen[-1].estimated_rmse > 0
    assert status.state == "done" and status.frames_acknowledged == [0]


def test_idiff_finds_the_python_frame_identical_to_the_cli_exr(worker_farm, scratch):
    """OpenImageIO's own comparison, without tolerance, of the array written out and the CLI's EXR."""
    whitted = harness.scene("scenes/whitted.json")
    with tessera.Farm(worker_farm.address) as farm:
        (frame,) = list(farm.submit(whitted, width=64, height=48, spp=4).frames())
    assert_frame_is_render(frame, whitted, scratch, error_channels=False)
    mine = os.path.join(scratch, "python.pfm")
    harness.write_pfm(mine, frame.rgb)
    r = harness.idiff_identical(mine, os.path.join(scratch, "render_0000.exr"))
    assert r.returncode == 0 and "PASS" in r.stdout, r.stdout + r.stderr
    # And idiff does see a one-ulp change: the comparison above can fail.
    frame.rgb[10, 20, 1] = np.nextafter(frame.rgb[10, 20, 1], np.float32(1e9))
    harness.write_pfm(mine, frame.rgb)
    assert harness.idiff_identical(mine, os.path.join(scratch, "render_0000.exr")).returncode != 0


def test_multi_frame_job_frames_are_acknowledged_only_once_taken(worker_farm, scratch):
    anim = scenes.animated_json(os.path.join(scratch, "anim", "anim.json"), frames=4)
    with tessera.Farm(worker_farm.address) as farm:
        job = farm.submit(anim, frames="1-3", width=64, height=48, spp=4, tile_size=16)
        assert job.submitted is not None and (job.submitted.first_frame, job.submitted.last_frame) == (1, 3)

        # A consumer that stops after its first frame has not taken it: it stays unacknowledged.
        it = job.frames(error_channels=True)
        first = next(it)  # frames come as they complete: with two workers, not always in order
        assert first.index in (1, 2, 3)
        assert job.status().frames_acknowledged == []
        it.close()
        assert job.status().frames_acknowledged == []

        # A new watch gets it again, with the rest; each is acknowledged when the next is asked for.
        got = []
        acked_when_taken = []
        for frame in job.frames(error_channels=True):
            acked_when_taken.append(job.status().frames_acknowledged)
            got.append(frame)
        status = job.status()
    assert sorted(f.index for f in got) == [1, 2, 3]
    # When a frame is handed over, exactly the frames handed over before it are acknowledged.
    assert [sorted(a) for a in acked_when_taken] == [sorted(f.index for f in got[:i]) for i in range(3)]
    assert sorted(status.frames_acknowledged) == [1, 2, 3] and status.state == "done"
    again = next(f for f in got if f.index == first.index)
    np.testing.assert_array_equal(harness.bits(first.rgb), harness.bits(again.rgb))
    for frame in got:
        assert_frame_is_render(frame, anim, scratch, error_channels=True)
    # The frames differ (the ball moves): the comparison is frame by frame, not of one image.
    assert not np.array_equal(got[0].rgb, got[1].rgb)


def test_progress_iterator_follows_the_job_to_its_end(worker_farm, scratch):
    anim = scenes.animated_json(os.path.join(scratch, "p", "anim.json"), frames=2)
    with tessera.Farm(worker_farm.address) as farm:
        job = farm.submit(anim, width=64, height=48, spp=4, tile_size=16)
        updates = list(job.progress(interval=0.02))
        frames = list(job.frames())
    assert updates[-1].state == "done"
    assert updates[-1].tiles_done == updates[-1].tiles_total == 2 * 12
    assert updates[-1].frames_done == updates[-1].frames_total == 2
    assert all(a.tiles_done <= b.tiles_done for a, b in zip(updates, updates[1:]))
    assert sorted(f.index for f in frames) == [0, 1]


def test_the_readme_example_runs_against_a_real_farm(worker_farm, scratch):
    """README.md's "From Python" section as written: its install command (in a scratch folder
    whose python/ and proto/ are the repository's, so the venv it makes lands there), then its
    ```python block with that venv's python, from the repository root, the coordinator's address
    in TESSERA_COORDINATOR."""
    with open(os.path.join(harness.SOURCE_DIR, "README.md"), encoding="utf-8") as f:
        readme = f.read()
    section = readme.split("## From Python", 1)[1].split("\n## ", 1)[0]
    install = section.split("```sh\n", 1)[1].split("```", 1)[0]
    code = section.split("```python\n", 1)[1].split("```", 1)[0]
    for folder in ("python", "proto"):
        os.symlink(os.path.join(harness.SOURCE_DIR, folder), os.path.join(scratch, folder))
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    r = subprocess.run(["bash", "-euc", install], cwd=scratch, env=env, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stdout + r.stderr
    venv_python = os.path.join(scratch, ".venv", "bin", "python")
    assert os.path.isfile(venv_python), install
    env["TESSERA_COORDINATOR"] = worker_farm.address
    r = subprocess.run([venv_python, "-c", code], cwd=harness.SOURCE_DIR, env=env, capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "frame 0: (180, 320, 3)" in r.stdout, r.stdout


def test_an_output_given_to_submit_is_where_tessera_collect_writes_the_frames(worker_farm, scratch):
    anim = scenes.animated_json(os.path.join(scratch, "anim", "anim.json"), frames=2)
    pattern = os.path.join(scratch, "share", "..", "share", "f_####.exr")
    with tessera.Farm(worker_farm.address) as farm:
        job = farm.submit(anim, width=64, height=48, spp=4, tile_size=16, output=pattern)
        assert job.submitted.output == os.path.join(scratch, "share", "f_####.exr")  # absolute, normalized
        for _ in job.progress(interval=0.05):
            pass  # to its end, nobody taking the frames
    # The submitting process has let go of the job: a collector writes its frames where it said.
    r = worker_farm.cli("collect", "--once", "--poll", "0.2")
    assert "job " + job.id in r.stdout
    for f in (0, 1):
        got = harness.read_exr(os.path.join(scratch, "share", f"f_{f:04d}.exr"), scratch)
        want = harness.render(anim, f, scratch, *SIZE)
        for c in "RGB":
            np.testing.assert_array_equal(harness.bits(got[c]), harness.bits(want[c]), err_msg=f"frame {f} {c}")
