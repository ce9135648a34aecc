# SPDX-License-Identifier: Apache-2.0
import bpy

from . import farm_package


class TesseraAddonPreferences(bpy.types.AddonPreferences):
    bl_idname = __package__

    package_path: bpy.props.StringProperty(
        name="Tessera Python package",
        description=("Folder holding Tessera's Python package 'tessera' (e.g. tessera/build/python), or the "
                     "package folder itself. Empty: the environment variable TESSERA_PYTHONPATH, then "
                     "Blender's sys.path"),
        subtype="DIR_PATH",
        default="",
    )

    def draw(self, context):
        layout = self.layout
        layout.prop(self, "package_path")
        try:
            module = farm_package.import_tessera(self.package_path)
            layout.label(text="Found: " + str(getattr(module, "__file__", module)), icon="CHECKMARK")
        except farm_package.FarmPackageError as e:
            layout.label(text=str(e)[:200], icon="ERROR")


def preference_path(context=None):
    context = context or bpy.context
    addon = context.preferences.addons.get(__package__)
    return addon.preferences.package_path if addon is not None else ""
