# SPDX-License-Identifier: Apache-2.0
"""Zips blender/tessera_blender as Blender's Install... button takes it (what the CMake target
tessera_blender_zip makes). No bpy: the tests' drivers use it too."""

import os
import zipfile

MODULE = "tessera_blender"
SOURCE = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), MODULE)


def make(path, source=SOURCE):
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        for name in sorted(os.listdir(source)):
            if name.endswith(".py"):
                z.write(os.path.join(source, name), f"{MODULE}/{name}")
    return path
