# SPDX-License-Identifier: Apache-2.0
"""Small scenes the tests write: an animated JSON scene, glTF files with external buffers and
images, OBJ meshes with material libraries. Quick to render at test sizes."""

from __future__ import annotations

import json
import os
import struct
import zlib


def write(path: str, content: str | bytes) -> str:
    os.makedirs(os.path.dirname(path) or ".", exist_ok=True)
    with open(path, "wb") as f:
        f.write(content.encode() if isinstance(content, str) else content)
    return path


def animated_json(path: str, frames: int = 3, extra_objects: list | None = None) -> str:
    """Spheres over a checker floor, a ball moving over ``frames`` frames; glass and a mirror
    so rays bounce."""
    keys = [{"frame": 0, "translate": [0, 0, 0]}]
    if frames > 1:
        keys.append({"frame": frames - 1, "translate": [1.2, 0.6, 0.3]})
    doc = {
        "camera": {"position": [0, 1.4, 5.5], "look_at": [0, 0.7, 0], "up": [0, 1, 0], "vfov_deg": 40},
        "image": {"width": 96, "height": 64, "spp": 8, "max_depth": 6, "seed": 7},
        "background": [0.3, 0.45, 0.75],
        "lights": [{"type": "point", "position": [-3, 5, 4], "intensity": 120}],
        "materials": {
            "floor": {"type": "diffuse", "albedo": [0.8, 0.8, 0.8],
                      "checker": {"albedo2": [0.2, 0.25, 0.3], "scale": 0.5}},
            "red": {"type": "diffuse", "albedo": [0.8, 0.2, 0.1]},
            "glass": {"type": "glass", "ior": 1.5},
            "mirror": {"type": "mirror", "reflectance": 0.9},
        },
        "objects": [
            {"type": "plane", "name": "floor", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "floor"},
            {"type": "sphere", "name": "ball", "center": [-1, 0.6, 0], "radius": 0.6, "material": "red"},
            {"type": "sphere", "name": "glass", "center": [0.6, 0.5, 1], "radius": 0.5, "material": "glass"},
            {"type": "sphere", "name": "mirror", "center": [1.4, 0.8, -1], "radius": 0.8, "material": "mirror"},
        ] + (extra_objects or []),
        "animation": {"frames": frames, "objects": {"ball": keys}},
    }
    return write(path, json.dumps(doc, indent=1))


def png_1x1(rgb: tuple[int, int, int] = (200, 120, 40)) -> bytes:
    """A valid 1x1 RGB PNG."""
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    raw = b"\0" + bytes(rgb)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", 1, 1, 8, 2, 0, 0, 0)) +
            chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


def quad_gltf(path: str, buffer_uri: str, image_uri: str | None = None, camera: bool = True) -> str:
    """A .gltf: a quad (two triangles) whose vertices and indices are in the external buffer
    ``buffer_uri`` (URI-encoded as written; the file is written under its decoded name), a camera
    at z = 5, and optionally a texture from the external image ``image_uri``."""
    folder = os.path.dirname(path)
    positions = struct.pack("<12f", -1, -1, 0, 1, -1, 0, 1, 1, 0, -1, 1, 0)
    uvs = struct.pack("<8f", 0, 1, 1, 1, 1, 0, 0, 0)
    indices = struct.pack("<6H", 0, 1, 2, 0, 2, 3)
    data = positions + uvs + indices
    from urllib.parse import unquote
    write(os.path.join(folder, unquote(buffer_uri)), data)
    doc: dict = {
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0, 1] if camera else [0]}],
        "nodes": [{"mesh": 0, "name": "quad"}, {"camera": 0, "translation": [0, 0, 5]}],
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.8, "aspectRatio": 1.5, "znear": 0.1}}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 2}, "indices": 1}]}],
        "buffers": [{"uri": buffer_uri, "byteLength": len(data)}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48},
                        {"buffer": 0, "byteOffset": 80, "byteLength": 12},
                        {"buffer": 0, "byteOffset": 48, "byteLength": 32}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
                       "min": [-1, -1, 0], "max": [1, 1, 0]},
                      {"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"},
                      {"bufferView": 2, "componentType": 5126, "count": 4, "type": "VEC2"}],
    }
    if image_uri is not None:
        write(os.path.join(folder, unquote(image_uri)), png_1x1())
        doc["images"] = [{"uri": image_uri}]
        doc["textures"] = [{"source": 0}]
        doc["materials"] = [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]
        doc["meshes"][0]["primitives"][0]["material"] = 0
    if not camera:
        del doc["nodes"][1], doc["cameras"]
    return write(path, json.dumps(doc))


def obj_with_mtl(path: str, mtllib: str, mtl_file: str | None) -> str:
    """An OBJ square whose ``mtllib`` line names ``mtllib``; the library written as ``mtl_file``
    (relative to the OBJ; None: none written)."""
    folder = os.path.dirname(path)
    if mtl_file is not None:
        write(os.path.join(folder, mtl_file), "newmtl red\nKd 0.8 0.1 0.1\nillum 2\n")
    return write(path, f"mtllib {mtllib}\no square\nv -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nusemtl red\n"
                       "f 1 2 3\nf 1 3 4\n")


def json_with(path: str, **fields: object) -> str:
    """A small valid JSON scene (camera, a light, a floor) plus ``fields`` (objects are appended)."""
    doc: dict = {
        "camera": {"position": [0, 2, 6], "look_at": [0, 0, 0]},
        "image": {"width": 32, "height": 24, "spp": 2},
        "lights": [{"type": "point", "position": [2, 4, 3], "intensity": 50}],
        "materials": {"grey": {"type": "diffuse", "albedo": [0.6, 0.6, 0.6]}},
        "objects": [{"type": "plane", "point": [0, -1, 0], "normal": [0, 1, 0], "material": "grey"}],
    }
    objects = fields.pop("objects", [])
    doc["objects"] += objects
    doc.update(fields)
    return write(path, json.dumps(doc))
