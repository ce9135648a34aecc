# SPDX-License-Identifier: Apache-2.0
"""The bundle Python builds is the CLI's, byte for byte: `tessera submit --detach` of the same scene
names the same bundle_sha256 and finds it already uploaded (HasBundle), and the other way round."""

from __future__ import annotations

import os
import re

import pytest

import harness
import scenes
import tessera

TINY = ["--width", "8", "--height", "8", "--spp", "1"]


def cli_submit(farm: harness.LocalFarm, scene_path: str) -> tuple[str, bool]:
    """`tessera submit SCENE --detach`: its job's bundle hash, and whether the CLI uploaded it."""
    r = farm.cli("submit", scene_path, "--detach", *TINY)
    job_id = re.search(r"^job (\S+) submitted", r.stdout, re.M).group(1)
    with tessera.Farm(farm.address) as f:
        sha = f.job(job_id).status().bundle_sha256
    return sha, "uploaded scene bundle" in r.stdout


def crafted_scenes(root: str) -> dict[str, str]:
    """Scenes whose files the loaders find in their own ways (bundle.py's docstring)."""
    out = {}
    # A .gltf with its buffer and texture outside it, names percent-encoded (tinygltf decodes them).
    out["gltf with external files"] = scenes.quad_gltf(os.path.join(root, "a", "export", "s.gltf"), "s%20data.bin",
                                                       "tex%20one.png")
    # A JSON scene including that glTF and adding to it.
    out["json including a gltf"] = scenes.json_with(
        os.path.join(root, "a", "edit.json"), include="export/s.gltf",
        objects=[{"type": "sphere", "center": [0, 0, 0], "radius": 0.5, "material": "grey"}])
    # Meshes: a glTF mesh through assimp (its buffer, not decoded), an OBJ whose mtllib has a
    # space, the same OBJ again with exclusions, an OBJ whose mtllib is missing (assimp falls back
    # to its own name with .mtl), and one beside the scene's folder whose library climbs further.
    scenes.quad_gltf(os.path.join(root, "b", "parts", "quad.gltf"), "quad_b.bin", camera=False)
    scenes.obj_with_mtl(os.path.join(root, "b", "models", "sq.obj"), "sq lib.mtl", "sq lib.mtl")
    scenes.obj_with_mtl(os.path.join(root, "b", "models", "fb.obj"), "nope.mtl", "fb.mtl")
    scenes.obj_with_mtl(os.path.join(root, "shared", "up.obj"), "../mat/up.mtl", "../mat/up.mtl")
    out["json with meshes and their libraries"] = scenes.json_with(os.path.join(root, "b", "scene.json"), objects=[
        {"type": "mesh", "file": "parts/quad.gltf"},
        {"type": "mesh", "file": "models/sq.obj"},
        {"type": "mesh", "file": "models/sq.obj", "exclude": ["nothing"]},
        {"type": "mesh", "file": "models/fb.obj"},
        {"type": "mesh", "file": "../shared/up.obj"},
    ])
    # One file under two spellings: one entry (the CLI refused such a bundle before, "appears twice").
    out["one mesh under two spellings"] = scenes.json_with(os.path.join(root, "b", "twice.json"), objects=[
        {"type": "mesh", "file": "models/sq.obj"},
        {"type": "mesh", "file": "models/../models/sq.obj", "exclude": ["nothing"]},
    ])
    return out


@pytest.mark.parametrize("relative", ["scenes/bunny.json", "scenes/cornell.json", "tests/data/gltf/whitted_a.glb"])
def test_repository_scenes_hash_as_the_cli_hashes_them(bare_farm, relative):
    path = harness.scene(relative)
    with tessera.Farm(bare_farm.address) as farm:
        job = farm.submit(path, width=8, height=8, spp=1)
        assert job.status().bundle_sha256 == job.bundle.sha256
    assert job.bundle is not None and job.bundle.uploaded
    cli_sha, cli_uploaded = cli_submit(bare_farm, path)
    assert cli_sha == job.bundle.sha256
    assert not cli_uploaded  # HasBundle found Python's upload: the CLI had nothing to send
    if relative.endswith(".json"):
        assert len(job.bundle.files) >= 2  # the scene and its meshes (and an OBJ's material library)


def test_crafted_scenes_hash_as_the_cli_hashes_them(bare_farm, scratch):
    for what, path in crafted_scenes(scratch).items():
        # The CLI first this time: Python finds the bundle there and uploads nothing.
        cli_sha, cli_uploaded = cli_submit(bare_farm, path)
        assert cli_uploaded, what
        with tessera.Farm(bare_farm.address) as farm:
            info = farm.upload(path)
        assert info.sha256 == cli_sha, f"{what}: {info.files}"
        assert not info.uploaded, what
    files = tessera.make_bundle(os.path.join(scratch, "b", "scene.json")).files
    assert files == ["b/scene.json", "mat/up.mtl", "shared/up.obj", "b/models/fb.mtl", "b/models/fb.obj",
                     "b/models/sq lib.mtl", "b/models/sq.obj", "b/parts/quad.gltf", "b/parts/quad_b.bin"]
    assert tessera.make_bundle(os.path.join(scratch, "b", "twice.json")).files == [
        "twice.json", "models/sq lib.mtl", "models/sq.obj"]
    assert tessera.scene_dependencies(os.path.join(scratch, "a", "edit.json")) == [
        "export/s data.bin", "export/s.gltf", "export/tex one.png"]


def test_a_bundle_is_uploaded_once_in_chunks_and_the_coordinator_checks_its_hash(bare_farm, scratch):
    """A bundle over one chunk (1 MiB) goes in several UploadBundle messages and hashes right (the
    coordinator recomputes the hash and refuses a mismatch); the second submit uploads nothing."""
    path = scenes.json_with(os.path.join(scratch, "big", "big.json"),
                            objects=[{"type": "mesh", "file": "pad.obj", "material": "grey"}])
    # 2.5 MiB of OBJ: three chunks.
    with open(os.path.join(scratch, "big", "pad.obj"), "w") as f:
        f.write("v -1 0 -1\nv 1 0 -1\nv 1 0 1\nf 1 2 3\n")
        f.write("# padding\n" * (250 * 1024))
    with tessera.Farm(bare_farm.address) as farm:
        first = farm.submit(path, spp=1, width=8, height=8)
        second = farm.submit(path, spp=1, width=8, height=8)
    assert first.bundle.uploaded and first.bundle.size > 2 << 20
    assert not second.bundle.uploaded and second.bundle.sha256 == first.bundle.sha256
    assert cli_submit(bare_farm, path) == (first.bundle.sha256, False)
