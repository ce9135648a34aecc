# SPDX-License-Identifier: Apache-2.0
"""Tessera render farm add-on for Blender: render the scene on a Tessera farm.

The scene is exported to glTF 2.0 (.glb) with its cameras and punctual lights, submitted to a
Tessera coordinator through the Python package ``tessera``, and the finished frames come back as
float Blender images and float32 OpenEXR files at the scene's output path.

The add-on is a separate program from Tessera itself: it talks to the farm through the
``tessera`` package (gRPC) and links nothing into Tessera.
"""

bl_info = {
    "name": "Tessera render farm",
    "author": "The Tessera authors",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "Properties > Render > Tessera farm",
    "description": "Render the scene on a Tessera render farm (exported as glTF 2.0)",
    "category": "Render",
}

if "bpy" in locals():  # "Reload scripts": pick up edited submodules
    import importlib

    for _m in (farm_package, frames, export, images, session, props, prefs, operators, ui):  # noqa: F821
        importlib.reload(_m)
else:
    from . import farm_package, frames, export, images, session, props, prefs, operators, ui

import bpy  # noqa: E402

_classes = (
    prefs.TesseraAddonPreferences,
    props.TesseraSceneSettings,
    operators.TESSERA_OT_render,
    operators.TESSERA_OT_cancel,
    ui.TESSERA_PT_farm,
)


def register():
    for cls in _classes:
        bpy.utils.register_class(cls)
    bpy.types.Scene.tessera = bpy.props.PointerProperty(type=props.TesseraSceneSettings)


def unregister():
    session.shutdown_all()
    del bpy.types.Scene.tessera
    for cls in reversed(_classes):
        bpy.utils.unregister_class(cls)
