#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Runs the shell commands of README.md's "## From Blender" section as a user would, so they
cannot rot. Started by run_blender_test.py --readme README.md --farm main (which sets the farm,
the Blender user folders and PATH in the environment).

The commands run verbatim in a folder laid out like the repository root: build/blender/
tessera_blender.zip (zipped from blender/ now, as the CMake target tessera_blender_zip makes it),
build/python (a link to the built package) and scene.blend (made here: two frames, its output
path //render/frame_####). The one substitution: the coordinator address 127.0.0.1:7878 becomes
the test farm's. Then the frames must be at the output path, as float32 EXR, and the job done at
the coordinator.
"""

import json
import os
import re
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
README_ADDRESS = "127.0.0.1:7878"


def section(readme, title="## From Blender"):
    text = open(readme, encoding="utf-8").read()
    start = text.index(title + "\n")
    end = text.find("\n## ", start + len(title))
    return text[start:end if end >= 0 else len(text)]


def shell_blocks(text):
    return re.findall(r"```sh\n(.*?)```", text, flags=re.S)


def run(cmd, cwd, env, **kw):
    print("+", cmd if isinstance(cmd, str) else " ".join(cmd), flush=True)
    p = subprocess.run(cmd, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, **kw)
    out = p.stdout.decode(errors="replace")
    print(out, flush=True)
    if p.returncode != 0:
        sys.exit(f"readme_example: exit status {p.returncode}")
    if "Traceback (most recent call last)" in out or "Error:" in out:
        sys.exit("readme_example: a traceback or an error in the output")
    return out


def main():
    readme = sys.argv[1]
    address = os.environ["TESSERA_TEST_FARM_MAIN"]
    package = os.environ["TESSERA_PYTHONPATH"]
    blender = os.environ.get("BLENDER", "blender")
    root = os.path.join(os.environ["TESSERA_TEST_TMP"], "repo")
    os.makedirs(os.path.join(root, "build", "blender"))
    os.symlink(package, os.path.join(root, "build", "python"))

    sys.path.insert(0, HERE)
    env = dict(os.environ)
    env.pop("TESSERA_PYTHONPATH")  # the README's commands must say where the package is
    env.pop("TESSERA_CLIENT_TOKEN", None)

    # The add-on's zip, as `cmake --build build --target tessera_blender_zip` leaves it.
    import addon_zip

    addon_zip.make(os.path.join(root, "build", "blender", "tessera_blender.zip"))
    scene = ("import sys, bpy; sys.path.insert(0, %r); import blender_test_lib as T; "
             "s = T.build_scene(animated=True, frame_start=1, frame_end=2); "
             "s.render.filepath = '//render/frame_####'; "
             "bpy.ops.wm.save_as_mainfile(filepath=%r)") % (HERE, os.path.join(root, "scene.blend"))
    run([blender, "-b", "--factory-startup", "--python-exit-code", "1", "--python-expr", scene], root, env)

    blocks = shell_blocks(section(readme))
    assert len(blocks) >= 2, f"expected the install and the render commands in {readme}, got {len(blocks)} blocks"
    assert any("tessera_blender.zip" in b for b in blocks), "no install command"
    assert any("bpy.ops.tessera.render()" in b and README_ADDRESS in b for b in blocks), "no render command"
    outputs = [run(["bash", "-euo", "pipefail", "-c", b.replace(README_ADDRESS, address)], root, env) for b in blocks]

    for frame in (1, 2):
        path = os.path.join(root, "render", f"frame_{frame:04d}.exr")
        assert os.path.isfile(path), f"{path} was not written"
        info = subprocess.run(["oiiotool", "--info", "-v", path], check=True, stdout=subprocess.PIPE).stdout.decode()
        assert "64 x   48, 3 channel, float openexr" in info, info
    m = re.search(r"Tessera job ([0-9a-f]+): 2 frames done", "".join(outputs))
    assert m, "the render command did not report its job"
    job = json.loads(subprocess.run([os.environ["TESSERA_CLI"], "status", m.group(1), "--coordinator", address,
                                     "--json"], check=True, stdout=subprocess.PIPE).stdout)
    job = job[0] if isinstance(job, list) else job
    assert job["state"] == "done" and (job["first_frame"], job["last_frame"], job["spp"]) == (1, 2, 16), job
    assert sorted(job["frames_acknowledged"]) == [1, 2], job
    print("readme_example: the README's commands installed the add-on and rendered frames 1-2 on the farm")


if __name__ == "__main__":
    main()
