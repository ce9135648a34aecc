# SPDX-License-Identifier: Apache-2.0
import bpy


class TesseraSceneSettings(bpy.types.PropertyGroup):
    """Per-scene farm settings: Scene.tessera."""

    address: bpy.props.StringProperty(
        name="Coordinator",
        description="HOST:PORT of the Tessera coordinator (tessera-server --listen)",
        default="127.0.0.1:7878",
    )
    token_file: bpy.props.StringProperty(
        name="Token file",
        description="File holding the client token the coordinator asks for (its --client-token-file); "
                    "empty: none",
        subtype="FILE_PATH",
        default="",
    )
    quality: bpy.props.EnumProperty(
        name="Quality",
        description="How long each pixel is sampled",
        items=(
            ("SPP", "Samples", "A fixed number of samples per pixel"),
            ("TARGET", "Target error", "Sample until the frame's estimated RMSE (linear light) is at most the target"),
        ),
        default="SPP",
    )
    spp: bpy.props.IntProperty(
        name="Samples", description="Samples per pixel", default=16, min=1, max=65536, soft_max=4096)
    target_rmse: bpy.props.FloatProperty(
        name="Target RMSE", description="Estimated RMSE (linear light) each frame is rendered down to",
        default=0.01, min=1e-6, soft_max=1.0, precision=4, step=0.1)
    frames: bpy.props.EnumProperty(
        name="Frames",
        items=(
            ("RANGE", "Frame range", "Every frame from the scene's Frame Start to Frame End"),
            ("CURRENT", "Current frame", "The scene's current frame only"),
        ),
        default="RANGE",
    )
    priority: bpy.props.IntProperty(
        name="Priority", description="Higher runs first on the farm", default=0, min=-1000000, max=1000000)
    timeout: bpy.props.FloatProperty(
        name="Timeout", description="Seconds to wait for the coordinator to answer a call",
        default=30.0, min=0.5, max=3600.0, subtype="TIME_ABSOLUTE", unit="TIME_ABSOLUTE")
    load_images: bpy.props.BoolProperty(
        name="Load images", description="Load every finished frame as a float Blender image", default=True)
    write_files: bpy.props.BoolProperty(
        name="Write EXR files",
        description="Write every finished frame to the output path as a float32 OpenEXR file", default=True)
    last_job_id: bpy.props.StringProperty(
        name="Last job", description="The id of the last job submitted from this scene", default="")
