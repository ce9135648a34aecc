# SPDX-License-Identifier: Apache-2.0
"""Faults under a watching client: a worker killed with SIGKILL mid-job loses its leases and
another renders them; a coordinator killed and restarted mid-job is re-attached to. Either way
Job.frames() yields every frame complete and bit for bit `tessera render`'s."""

from __future__ import annotations

import logging
import os
import signal
import threading
import time
from typing import Callable

import numpy as np

import harness
import scenes
import tessera

SIZE = ["--width", "64", "--height", "48", "--spp", "4"]


class Watcher:
    """A client watching the job all along on its own thread (as the Blender add-on does)."""

    def __init__(self, job: tessera.Job) -> None:
        self.frames: list[tessera.Frame] = []
        self.failure: list[BaseException] = []
        self.thread = threading.Thread(target=self._run, args=(job,))
        self.thread.start()

    def _run(self, job: tessera.Job) -> None:
        try:
            self.frames.extend(job.frames(error_channels=True))
        except BaseException as e:  # reported by join()
            self.failure.append(e)

    def join(self, timeout: float = 60) -> list[tessera.Frame]:
        self.thread.join(timeout)
        assert not self.thread.is_alive(), "frames() did not end"
        assert not self.failure, self.failure
        return self.frames


def wait_until(condition: Callable[[], bool], what: str, timeout: float = 30) -> None:
    end = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < end, what
        time.sleep(0.01)


def assert_frames_are_renders(frames: list[tessera.Frame], scene_path: str, scratch: str, count: int) -> None:
    assert sorted(f.index for f in frames) == list(range(count))
    for fr in frames:
        want = harness.render(scene_path, fr.index, scratch, *SIZE, "--error-channels")
        for i, c in enumerate("RGB"):
            np.testing.assert_array_equal(harness.bits(fr.rgb[:, :, i]), harness.bits(want[c]))
        np.testing.assert_array_equal(harness.bits(fr.error), harness.bits(want["error.Y"]))
        np.testing.assert_array_equal(fr.spp.astype(np.float32), want["spp.Y"])


def test_a_worker_killed_mid_job_still_gives_every_frame_complete_and_correct(make_farm, scratch):
    farm = make_farm()
    # Worker a renders slowly (40 ms a tile), so the job is well under way, not done, when it dies.
    a = farm.add_worker("a", extra=["--test-delay-ms", "40"])
    farm.wait_for_workers(["a"])
    anim = scenes.animated_json(os.path.join(scratch, "anim.json"), frames=3)
    with tessera.Farm(farm.address) as f:
        job = f.submit(anim, width=64, height=48, spp=4, tile_size=16)
        watcher = Watcher(job)
        wait_until(lambda: job.status().tiles_done >= 2, "worker a rendered nothing")
        # Frozen first, so the state it dies in is the state checked: holding leases, job unfinished.
        a.signal(signal.SIGSTOP)
        st = job.status()
        assert st.state == "running" and 2 <= st.tiles_done < st.tiles_total and st.tiles_leased > 0, st
        a.signal(signal.SIGKILL)
        a.proc.wait(10)
        farm.add_worker("b")
        frames = watcher.join()
        final = job.status()
        names = [w.name for w in f.workers()]
    assert final.state == "done" and final.tiles_done == final.tiles_total == 36
    assert sorted(final.frames_acknowledged) == [0, 1, 2]
    assert names == ["b"]  # a's stream broke: it is gone, its leases went back to the queue
    assert_frames_are_renders(frames, anim, scratch, 3)


def test_a_coordinator_killed_and_restarted_mid_job_is_reattached_to(make_farm, scratch, caplog):
    caplog.set_level(logging.WARNING, logger="tessera")
    farm = make_farm()
    farm.add_worker("w", extra=["--test-delay-ms", "30"])
    farm.wait_for_workers(["w"])
    anim = scenes.animated_json(os.path.join(scratch, "anim.json"), frames=3)
    with tessera.Farm(farm.address) as f:
        job = f.submit(anim, width=64, height=48, spp=4, tile_size=16)
        watcher = Watcher(job)
        wait_until(lambda: len(watcher.frames) >= 1, "no frame arrived before the restart")
        assert job.status().state == "running"
        farm.kill_and_restart_server()  # the same address and data folder; the worker reconnects
        frames = watcher.join()
        final = job.status()
    assert final.state == "done" and sorted(final.frames_acknowledged) == [0, 1, 2]
    assert "lost the watch stream" in caplog.text and "re-attaching" in caplog.text  # it did lose it
    assert_frames_are_renders(frames, anim, scratch, 3)
