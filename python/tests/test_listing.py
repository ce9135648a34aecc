# SPDX-License-Identifier: Apache-2.0
"""farm.workers(), farm.jobs(), job.status() and job.set_priority() show what `tessera workers`,
`tessera status` and `tessera priority` show, and a new priority changes the dispatch order."""

from __future__ import annotations

import json
import os
import re
import time

import grpc
import pytest

import harness
import scenes
import tessera

# `tessera status --json` keys that JobStatus has under the same name.
SAME_KEYS = ["job_id", "name", "state", "priority", "first_frame", "last_frame", "width", "height", "spp",
             "tile_size", "tiles_total", "tiles_done", "tiles_leased", "tiles_rendered_twice", "rays", "frames_done",
             "frames_acknowledged", "error", "blocklisted_workers", "target_rmse", "block_rmse", "tiles_resident",
             "waiting_for_memory", "owner"]


def test_workers_are_what_the_cli_lists(worker_farm):
    with tessera.Farm(worker_farm.address) as farm:
        mine = farm.workers()
    cli = json.loads(worker_farm.cli("workers", "--json").stdout)
    stable = ["worker_id", "name", "peer", "threads", "embree_isa"]
    assert [[getattr(w, k) for k in stable] for w in mine] == [[w[k] for k in stable] for w in cli]
    assert sorted(w.name for w in mine) == ["w1", "w2"] and all(w.threads == 1 for w in mine)
    assert all(isinstance(w, tessera.WorkerInfo) and w.embree_isa.startswith("embree") for w in mine)


def test_jobs_and_priorities_are_what_the_cli_shows(bare_farm, scratch):
    anim = scenes.animated_json(os.path.join(scratch, "anim.json"), frames=3)
    with tessera.Farm(bare_farm.address) as farm:
        a = farm.submit(anim, frames="0-1", spp=2, width=32, height=24, name="listing a")
        b = farm.submit(anim, frames=2, target_rmse=0.02, max_spp=64, width=40, height=30, priority=3,
                        name="listing b")
        assert b.set_priority(12).priority == 12
        harness.run_cli("priority", a.id, "-5", "--coordinator", bare_farm.address)
        assert a.status().priority == -5
        jobs = {j.job_id: j for j in farm.jobs()}
        statuses = [a.status(), b.status()]
    cli = {j["job_id"]: j for j in json.loads(bare_farm.cli("status", "--json").stdout)}
    assert set(cli) == set(jobs) and {a.id, b.id} <= set(jobs)
    for job_id, mine in jobs.items():
        assert {k: getattr(mine, k) for k in SAME_KEYS} == {k: cli[job_id][k] for k in SAME_KEYS}, job_id
        assert mine.output == (cli[job_id]["output"] or {}).get("pattern"), job_id
    for st in statuses:
        one = json.loads(bare_farm.cli("status", st.job_id, "--json").stdout)
        assert {k: getattr(st, k) for k in SAME_KEYS} == {k: one[k] for k in SAME_KEYS}
    sa, sb = statuses
    assert (sa.state, sa.priority, sa.first_frame, sa.last_frame, sa.spp) == ("queued", -5, 0, 1, 2)
    assert (sb.priority, sb.first_frame, sb.last_frame, sb.target_rmse, sb.spp) == (12, 2, 2, 0.02, 64)
    assert sb.name == "listing b" and sb.width == 40 and sb.tiles_total == 2  # 32-pixel tiles: 2 x 1


def test_a_jobs_recorded_output_and_owner_are_what_the_cli_shows(bare_farm, scratch):
    anim = scenes.animated_json(os.path.join(scratch, "anim.json"), frames=2)
    pattern = os.path.join(scratch, "share", "f_####.exr")
    out = bare_farm.cli("submit", anim, "--detach", "--width", "16", "--height", "16", "-o", pattern).stdout
    job_id = re.search(r"job ([0-9a-f]+) submitted", out).group(1)
    with tessera.Farm(bare_farm.address) as farm:
        st = {j.job_id: j for j in farm.jobs()}[job_id]
    assert st.output == pattern
    cli = json.loads(bare_farm.cli("status", job_id, "--json").stdout)
    assert cli["output"]["pattern"] == pattern and cli["owner"] == st.owner


def test_a_raised_priority_runs_first_and_an_ended_job_refuses_a_new_one(make_farm, scratch):
    farm = make_farm()
    anim = scenes.animated_json(os.path.join(scratch, "anim.json"), frames=1)
    with tessera.Farm(farm.address) as f:
        first = f.submit(anim, spp=2, width=64, height=48, tile_size=16)
        second = f.submit(anim, spp=2, width=64, height=48, tile_size=16)
        second.set_priority(5)  # queued, no worker yet: the second is now ahead
        farm.add_worker("only", extra=["--test-delay-ms", "5"])
        end = time.monotonic() + 60
        while not all(j.state == "done" for j in f.jobs()):
            assert time.monotonic() < end
            time.sleep(0.02)
        s1, s2 = first.status(), second.status()
        with pytest.raises(tessera.FarmError) as raised:
            first.set_priority(9)
        list(first.frames())
        list(second.frames())
    assert s2.submitted_unix + s2.elapsed_seconds < s1.submitted_unix + s1.elapsed_seconds
    assert raised.value.code == grpc.StatusCode.FAILED_PRECONDITION and type(raised.value) is tessera.FailedPrecondition
