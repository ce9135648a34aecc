# SPDX-License-Identifier: Apache-2.0
"""Farm.rays against a real tessera-rays gives `tessera rays`'s answers, bit for bit: on the server
named, on the one the coordinator lists, nearest hits, a field mask and occlusion."""

from __future__ import annotations

import os
import time

import grpc
import numpy as np
import pytest

import harness
import tessera

MISS = 4294967295


@pytest.fixture(scope="module")
def rays_farm(tmp_root):
    farm = harness.LocalFarm(tmp_root, "rays-farm")
    try:
        _, address = farm.add_ray_server()
        farm.ray_address = address
        with tessera.Farm(farm.address) as f:  # listed once its first announcement is in
            end = time.monotonic() + 20
            while not f.ray_servers():
                assert time.monotonic() < end, "tessera-rays was never listed"
                time.sleep(0.05)
        yield farm
    finally:
        farm.stop()


def make_rays(n: int = 3000) -> np.ndarray:
    """(n, 8): origins around the bunny, random directions (any length), some with intervals."""
    rng = np.random.default_rng(27)
    origins = rng.uniform([-2, 0.05, -2], [2, 2, 3], size=(n, 3))
    directions = rng.normal(size=(n, 3)) * rng.uniform(0.1, 10, size=(n, 1))
    directions[: n // 3] = np.array([0.0, 0.75, 0]) - origins[: n // 3]  # towards the bunny: hits
    t_min = np.where(np.arange(n) % 5 == 0, 0.01, 0.0)
    t_max = np.where(np.arange(n) % 7 == 0, 1.5, np.inf)
    return np.column_stack([origins, directions, t_min, t_max])


def cli_rays(farm: harness.LocalFarm, scene: str, rays: np.ndarray, scratch: str, *args: str) -> np.ndarray:
    src, out = os.path.join(scratch, "rays.npy"), os.path.join(scratch, "hits.npy")
    np.save(src, rays)
    harness.run_cli("rays", scene, "--in", src, "--out", out, "--coordinator", farm.address, *args)
    return np.load(out)


def names(hits: tessera.RayHits, indices: np.ndarray, table: list[str]) -> np.ndarray:
    """Indices as the CLI's .npy writes them: the name, '#i' for an unnamed one, '' for a miss."""
    return np.array([b"" if i == MISS else (table[i] or f"#{i}").encode() for i in indices])


def assert_same(hits: tessera.RayHits, want: np.ndarray) -> None:
    np.testing.assert_array_equal(hits.hit, want["hit"] == 1)
    np.testing.assert_array_equal(hits.t.view(np.uint32), want["t"].astype("<f4").view(np.uint32))
    for k, c in enumerate(("px", "py", "pz")):
        np.testing.assert_array_equal(hits.points[:, k].view(np.uint64), want[c].astype("<f8").view(np.uint64))
    for arr, cols in ((hits.normals, ("nx", "ny", "nz")), (hits.shading_normals, ("snx", "sny", "snz")),
                      (hits.barycentrics, ("u", "v"))):
        for k, c in enumerate(cols):
            np.testing.assert_array_equal(arr[:, k].view(np.uint32), want[c].astype("<f4").view(np.uint32))
    np.testing.assert_array_equal(np.where(hits.hit, hits.primitives.astype(np.int64), -1), want["primitive"])
    np.testing.assert_array_equal(names(hits, hits.objects, hits.object_names), want["object"])
    np.testing.assert_array_equal(names(hits, hits.materials, hits.material_names), want["material"])


def test_rays_on_a_named_server_are_the_clis(rays_farm, scratch):
    bunny = harness.scene("scenes/bunny.json")
    rays = make_rays()
    want = cli_rays(rays_farm, bunny, rays, scratch, "--server", rays_farm.ray_address)
    with tessera.Farm(rays_farm.address) as farm:
        hits = farm.rays(bunny, rays[:, 0:3], rays[:, 3:6], t_min=rays[:, 6], t_max=rays[:, 7],
                         server=rays_farm.ray_address, batch=1000)
    assert hits.server == rays_farm.ray_address and len(hits) == len(rays)
    assert 0.3 < hits.hit.mean() < 0.95  # hits and misses both
    assert "bunny" in hits.object_names
    assert_same(hits, want)
    assert hits["t"] is hits.t and "points" in hits.keys()


def test_rays_on_a_listed_server_with_a_mask_and_occlusion_are_the_clis(rays_farm, scratch):
    bunny = harness.scene("scenes/bunny.json")
    rays = make_rays(500)
    with tessera.Farm(rays_farm.address) as farm:
        assert [s.address for s in farm.ray_servers()] == [rays_farm.ray_address]
        # No server named: the one the coordinator lists, as `tessera rays --coordinator`.
        hits = farm.rays(bunny, rays[:, 0:3], rays[:, 3:6], t_min=rays[:, 6], t_max=rays[:, 7])
        assert hits.server == rays_farm.ray_address
        assert_same(hits, cli_rays(rays_farm, bunny, rays, scratch))
        t_only = farm.rays(bunny, rays[:, 0:3], rays[:, 3:6], t_min=rays[:, 6], t_max=rays[:, 7], fields=["t"])
        want = cli_rays(rays_farm, bunny, rays, scratch, "--fields", "t")
        assert t_only.keys() == ["hit", "t"] and t_only.points is None
        np.testing.assert_array_equal(t_only.t.view(np.uint32), want["t"].astype("<f4").view(np.uint32))
        occluded = farm.rays(bunny, rays[:, 0:3], rays[:, 3:6], t_min=rays[:, 6], t_max=rays[:, 7], occlusion=True)
        want = cli_rays(rays_farm, bunny, rays, scratch, "--occlusion")
        assert occluded.keys() == ["hit"]
        np.testing.assert_array_equal(occluded.hit, want["hit"] == 1)
        np.testing.assert_array_equal(occluded.hit, hits.hit)  # "occluded" is "has a nearest hit"


def test_bad_rays_are_refused_by_name(rays_farm):
    bunny = harness.scene("scenes/bunny.json")
    with tessera.Farm(rays_farm.address) as farm:
        with pytest.raises(ValueError, match=r"directions: expected shape \(N, 3\)"):
            farm.rays(bunny, np.zeros((2, 3)), np.zeros((2, 2)), server=rays_farm.ray_address)
        with pytest.raises(ValueError, match="origins has 2 rays, directions 3"):
            farm.rays(bunny, np.zeros((2, 3)), np.ones((3, 3)), server=rays_farm.ray_address)
        with pytest.raises(ValueError, match="fields: 'pointz' is not a hit field"):
            farm.rays(bunny, np.zeros((1, 3)), np.ones((1, 3)), fields=["pointz"])
        with pytest.raises(tessera.FarmError) as raised:
            farm.rays(bunny, np.zeros((2, 3)), np.array([[0, 0, 1.0], [0, 0, 0]]), server=rays_farm.ray_address)
    assert raised.value.code == grpc.StatusCode.INVALID_ARGUMENT
    assert "ray 1: direction is zero-length" in raised.value.message
