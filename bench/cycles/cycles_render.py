# Renders a glTF scene with Blender's Cycles restricted to Whitted-like transport, for
# bench/cycles/cycles_compare (the glTF peer). Blender runs as an external program only:
#
#   blender -b --factory-startup --python bench/cycles/cycles_render.py -- \
#       SCENE.glb OUT.exr WIDTH HEIGHT SPP MAX_DEPTH THREADS [NOISE_THRESHOLD]
#
# With NOISE_THRESHOLD > 0, Cycles' adaptive sampling (its noise threshold; SPP is then the most
# samples a pixel takes, the fewest Cycles' automatic minimum) instead of SPP everywhere.
#
# Whitted-like: no diffuse bounces (diffuse surfaces see lights directly only), specular
# (glossy) and transmission bounces up to MAX_DEPTH as Tessera's max_depth, caustics off, a 1-px
# box pixel filter (Tessera's), no denoising, no clamping, a black world (glTF has no background),
# the Standard view transform and a 32-bit float EXR: linear scene-referred values comparable with
# Tessera's EXR. Prints one line "CYCLES_RESULT {json}" with the render's wall and CPU seconds
# (the import and start-up left out, as Tessera's render time leaves out loading).
import json
import resource
import sys
import time

import bpy
import numpy

# Blender 3.4's glTF importer uses numpy.bool, removed in numpy 1.24 (Debian bookworm's).
if "bool" not in numpy.__dict__:
    numpy.bool = bool


def as_tessera_maps(material):
    """Replaces a material's Principled BSDF by the closure Tessera's nearest rule makes of it
    (docs/scene-format.md), so both renderers shade the same materials: a Lambert Diffuse BSDF
    (Principled's diffuse is Disney's, brighter at grazing angles, with a specular layer on top),
    a sharp Glossy BSDF for mirrors (metallic >= 0.5, roughness <= 0.5: constant reflectance, as
    Tessera's), a sharp Glass BSDF for transmission > 0 (IOR from the material). The base color,
    texture included, feeds the new closure. Returns the kind, for the log."""
    if not material or not material.use_nodes:
        return "none"
    nodes, links = material.node_tree.nodes, material.node_tree.links
    principled = next((n for n in nodes if n.type == "BSDF_PRINCIPLED"), None)
    output = next((n for n in nodes if n.type == "OUTPUT_MATERIAL"), None)
    if not principled or not output:
        return "other"
    i = principled.inputs
    if i["Transmission"].default_value > 0:
        kind, node = "glass", nodes.new("ShaderNodeBsdfGlass")
        node.distribution = "SHARP"
        node.inputs["IOR"].default_value = i["IOR"].default_value
    elif i["Metallic"].default_value >= 0.5 and i["Roughness"].default_value <= 0.5:
        kind, node = "mirror", nodes.new("ShaderNodeBsdfGlossy")
        node.distribution = "SHARP"
    else:
        kind, node = "diffuse", nodes.new("ShaderNodeBsdfDiffuse")
        node.inputs["Roughness"].default_value = 0  # Oren-Nayar with roughness 0 is Lambert
    base = i["Base Color"]
    if base.is_linked:
        links.new(base.links[0].from_socket, node.inputs["Color"])
    else:
        node.inputs["Color"].default_value = base.default_value
    links.new(node.outputs["BSDF"], output.inputs["Surface"])
    return kind


def cpu_seconds():
    u = resource.getrusage(resource.RUSAGE_SELF)  # every thread of this process: Cycles' too
    return u.ru_utime + u.ru_stime


def main(argv):
    scene_path, out, width, height, spp, depth, threads = argv[:7]
    width, height, spp, depth, threads = int(width), int(height), int(spp), int(depth), int(threads)
    threshold = float(argv[7]) if len(argv) > 7 else 0.0
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=scene_path)
    scene = bpy.context.scene
    cameras = [o for o in scene.objects if o.type == "CAMERA"]
    if not cameras:
        print("cycles_render: %s has no camera" % scene_path, file=sys.stderr)
        return 2
    # The first camera in the file's order, as Tessera picks it (object names keep the glTF's).
    scene.camera = cameras[0]
    kinds = {m.name: as_tessera_maps(m) for m in bpy.data.materials}
    # Point lights, as Tessera's: a point (hard shadows, unseen in mirrors); suns a single direction.
    for light in bpy.data.lights:
        if light.type in ("POINT", "SPOT"):
            light.shadow_soft_size = 0
        elif light.type == "SUN":
            light.angle = 0

    world = bpy.data.worlds.new("black")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0, 0, 0, 1)
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0
    scene.world = world

    r = scene.render
    r.engine = "CYCLES"
    r.resolution_x, r.resolution_y, r.resolution_percentage = width, height, 100
    r.threads_mode = "FIXED"
    r.threads = threads
    r.image_settings.file_format = "OPEN_EXR"
    r.image_settings.color_depth = "32"
    r.image_settings.exr_codec = "ZIP"
    r.filepath = out
    c = scene.cycles
    c.device = "CPU"
    c.samples = spp
    c.use_adaptive_sampling = threshold > 0
    if threshold > 0:
        c.adaptive_threshold = threshold
        c.adaptive_min_samples = 0  # Cycles' automatic minimum
    c.use_denoising = False
    c.seed = 0
    c.pixel_filter_type = "BOX"
    c.filter_width = 1.0
    c.max_bounces = depth
    c.diffuse_bounces = 0
    c.glossy_bounces = depth
    c.transmission_bounces = depth
    c.transparent_max_bounces = depth
    c.volume_bounces = 0
    c.caustics_reflective = False
    c.caustics_refractive = False
    c.sample_clamp_direct = 0
    c.sample_clamp_indirect = 0
    c.blur_glossy = 0
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0
    scene.view_settings.gamma = 1

    t0, c0 = time.time(), cpu_seconds()
    bpy.ops.render.render(write_still=True)
    wall, cpu = time.time() - t0, cpu_seconds() - c0
    print("CYCLES_RESULT " + json.dumps({"wall_s": wall, "cpu_s": cpu, "spp": spp, "width": width, "height": height,
                                         "max_depth": depth, "threads": threads, "noise_threshold": threshold, "blender": bpy.app.version_string,
                                         "materials": kinds}))
    return 0


if __name__ == "__main__":
    args = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    if len(args) not in (7, 8):
        print(__doc__ if __doc__ else "usage: see the header of cycles_render.py", file=sys.stderr)
        sys.exit(2)
    sys.exit(main(args))
