# SPDX-License-Identifier: Apache-2.0
"""Scene bundles built exactly as `tessera submit` builds them, so both give the same SHA-256.

A bundle is a serialized tessera.v1.Bundle: the scene file and every file it reads, paths relative
to their deepest common directory (lib/farm/bundle.cpp, make_bundle). Its identity is the SHA-256 of
those bytes, so the same scene uploaded from Python and from the CLI is stored once and a job from
either names the same bundle. That needs the same files in the same order with the same names, so
the list of files a scene reads (the C++ ``Scene::dependencies``) is worked out here the way the
loaders find them:

- a JSON scene (lib/scene/scene_parser.cpp): each mesh object's ``file`` as written, the side
  files its importer opens (an OBJ's ``mtllib``, a glTF mesh's buffers), relative to the mesh's
  folder and joined to it; an ``include``'d glTF's files behind its folder, then the include
  itself; sorted, each string once;
- a glTF scene (lib/scene/gltf_document.cpp through tinygltf): the external buffers and images it
  reads, resolved, relative to the glTF's folder, sorted, each once. A .glb carries its own.

This reads only what it needs to name the files; whether the scene is valid is the coordinator's
call (it answers INVALID_ARGUMENT with the parser's message).
"""

from __future__ import annotations

import hashlib
import json
import os
import struct
from dataclasses import dataclass
from typing import Any, Optional, Union

PathLike = Union[str, "os.PathLike[str]"]


@dataclass(frozen=True)
class Bundle:
    """A built bundle: its bytes, their SHA-256, and what it holds."""

    data: bytes
    sha256: str
    scene_file: str     # the scene's path inside the bundle
    files: list[str]    # every path inside the bundle, the scene first


def is_gltf_path(path: str) -> bool:
    """A glTF file by its extension, as lib/scene/gltf_scene.cpp decides (.gltf, .glb, any case)."""
    return os.path.splitext(os.path.basename(path))[1].lower() in (".gltf", ".glb")


def _read(path: str, what: str) -> bytes:
    try:
        with open(path, "rb") as f:
            return f.read()
    except FileNotFoundError:
        raise FileNotFoundError(2, f"{what} not found", path) from None
    except IsADirectoryError:
        raise IsADirectoryError(21, f"{what} is a directory, not a file", path) from None


def _resolved(path: str) -> str:
    """std::filesystem::weakly_canonical(absolute(path)): symlinks and '..' resolved."""
    return os.path.realpath(path)


def _relative(path: str, base: str) -> str:
    """path::lexically_relative of two resolved absolute paths, '/'-separated."""
    return os.path.relpath(path, base).replace(os.sep, "/")


def _join(a: str, b: str) -> str:
    """std::filesystem::path operator/ (an absolute b replaces a; an empty a leaves b)."""
    return os.path.join(a, b) if a else b


# --- glTF (tinygltf 2.7 as lib/scene/gltf_document.cpp drives it) --------------------------------

def _url_decode(uri: str) -> str:
    """tinygltf's dlib::urldecode: '+' is a space, '%XY' a byte (a non-hex digit counts as 0)."""
    raw = uri.encode("utf-8", "surrogateescape")
    out = bytearray()
    i = 0

    def hexval(c: int) -> int:
        for lo, hi, base in ((48, 57, 0), (97, 102, 10), (65, 70, 10)):
            if lo <= c <= hi:
                return c - lo + base
        return 0

    while i < len(raw):
        c = raw[i]
        if c == 0x2B:  # '+'
            out.append(0x20)
        elif c == 0x25 and len(raw) > i + 2:  # '%'
            out.append(((hexval(raw[i + 1]) << 4) | hexval(raw[i + 2])) & 0xFF)
            i += 2
        else:
            out.append(c)
        i += 1
    return bytes(out).decode("utf-8", "surrogateescape")


def _gltf_document(data: bytes, path: str) -> dict[str, Any]:
    """The JSON of a .gltf, or of a .glb's first chunk (a binary glTF is known by its magic)."""
    try:
        if data[:4] == b"glTF":
            if len(data) < 20:
                raise ValueError("truncated binary glTF header")
            length, kind = struct.unpack_from("<II", data, 12)
            if kind != 0x4E4F534A:  # 'JSON'
                raise ValueError("the first chunk of a binary glTF must be JSON")
            text = data[20:20 + length]
        else:
            text = data
        doc = json.loads(text.decode("utf-8"))
    except (ValueError, UnicodeDecodeError) as e:
        raise ValueError(f"{path}: invalid glTF: {e}") from None
    if not isinstance(doc, dict):
        raise ValueError(f"{path}: invalid glTF: the document is not a JSON object")
    return doc


def _gltf_dependencies(path: str) -> list[str]:
    """The files tinygltf reads for the glTF at ``path`` besides itself: relative to its resolved
    folder, sorted, each once (parse_gltf_scene's ``dependencies``)."""
    doc = _gltf_document(_read(path, "scene file"), path)
    base_dir = os.path.dirname(path)
    self_resolved = _resolved(path)
    uris: list[str] = []
    for buffer in doc.get("buffers") or []:
        if isinstance(buffer, dict) and isinstance(buffer.get("uri"), str):
            uris.append(buffer["uri"])
    for image in doc.get("images") or []:
        # An image in a bufferView is read from its buffer, never from a file.
        if isinstance(image, dict) and "bufferView" not in image and isinstance(image.get("uri"), str):
            uris.append(image["uri"])
    read: list[str] = []
    for uri in uris:
        if uri.startswith("data:"):
            continue
        name = _url_decode(uri).split("\0", 1)[0]
        if not name:
            continue
        # tinygltf's FindFile: the glTF's folder, then the current directory; a regular file only.
        for folder in (base_dir, "."):
            candidate = name if not folder else (folder + name if folder.endswith("/") else folder + "/" + name)
            if os.path.isfile(candidate):
                found = _resolved(candidate)
                if found != self_resolved:
                    read.append(_relative(found, os.path.dirname(self_resolved)))
                break
    return sorted(set(read))


# --- meshes (assimp, lib/scene/mesh_loader.cpp) -------------------------------------------------

def _obj_material_libraries(mesh_path: str) -> list[str]:
    """The files assimp's OBJ importer opens for ``mtllib`` lines, in order: the named library in
    the OBJ's folder, else (when that does not open) the OBJ's own name with .mtl."""
    data = _read(mesh_path, "mesh file")
    # The importer pushes the folder of the path it was given (up to its last '/' or '\\') and
    # opens the library as folder + '/' + name; without a folder, the name alone.
    cut = max(mesh_path.rfind("/"), mesh_path.rfind("\\"))
    folder = mesh_path[:cut] if cut > 0 else ""
    opened: list[str] = []
    for raw in data.replace(b"\r", b"\n").split(b"\n"):
        # The keyword is the first token of the line; the name is everything after the blanks
        # that follow it, up to the end of the line (assimp keeps inner and trailing blanks).
        if not raw.startswith(b"mtllib"):
            continue
        rest = raw[len(b"mtllib"):]
        if rest and rest[:1] not in (b" ", b"\t"):
            continue  # "mtllibx": another keyword
        name = rest.lstrip(b" \t").split(b"\0", 1)[0].split(b"\f", 1)[0].decode("utf-8", "surrogateescape")
        if not name:
            continue
        candidate = (folder if folder.endswith("/") else folder + "/") + name if folder else name
        # Not there: assimp tries the OBJ's own name with .mtl instead.
        if not os.path.isfile(candidate):
            candidate = mesh_path[:-3] + "mtl"  # m_originalObjFileName, its last 3 characters replaced
            if not os.path.isfile(candidate):
                continue
        opened.append(candidate)
    return opened


def _gltf_mesh_buffers(mesh_path: str) -> list[str]:
    """The external buffers assimp's glTF importer opens for a glTF used as a mesh: the URI as
    written, not percent-decoded (assimp 5.2 opens "a%20b.bin" literally); images it only names."""
    doc = _gltf_document(_read(mesh_path, "mesh file"), mesh_path)
    folder = os.path.dirname(mesh_path)
    opened = []
    for buffer in doc.get("buffers") or []:
        uri = buffer.get("uri") if isinstance(buffer, dict) else None
        if isinstance(uri, str) and uri and not uri.startswith("data:"):
            candidate = _join(folder, uri)
            if os.path.isfile(candidate):
                opened.append(candidate)
    return opened


def _mesh_side_files(mesh_path: str) -> list[str]:
    """The other files the mesh's importer reads, relative to the mesh's resolved folder, each once,
    in the order read (MeshLoadResult::side_files)."""
    ext = os.path.splitext(mesh_path)[1].lower()
    if ext == ".obj":
        opened = _obj_material_libraries(mesh_path)
    elif ext in (".gltf", ".glb"):
        opened = _gltf_mesh_buffers(mesh_path)
    else:
        opened = []  # PLY, STL and the other single-file formats
    self_resolved = _resolved(mesh_path)
    out: list[str] = []
    for p in opened:
        r = _resolved(p)
        rel = _relative(r, os.path.dirname(self_resolved))
        if r != self_resolved and rel not in out:
            out.append(rel)
    return out


# --- scenes --------------------------------------------------------------------------------------

def read_scene_json(path: str) -> dict[str, Any]:
    """A JSON scene file's document; ValueError naming the file, line and column for bad JSON."""
    data = _read(path, "scene file")
    try:
        doc = json.loads(data.decode("utf-8"))
    except json.JSONDecodeError as e:
        raise ValueError(f"{path}:{e.lineno}:{e.colno}: invalid JSON: {e.msg}") from None
    except UnicodeDecodeError as e:
        raise ValueError(f"{path}: invalid JSON: not UTF-8 ({e})") from None
    if not isinstance(doc, dict):
        raise ValueError(f"{path}: a scene file must be a JSON object")
    return doc


def json_dependencies(path: str, doc: dict[str, Any]) -> list[str]:
    folder = os.path.dirname(path)
    deps: list[str] = []
    include = doc.get("include")
    if isinstance(include, str) and is_gltf_path(include):
        include_folder = os.path.dirname(include)
        deps += [_join(include_folder, d).replace(os.sep, "/") for d in _gltf_dependencies(_join(folder, include))]
        deps.append(include)
    objects = doc.get("objects")
    for obj in objects if isinstance(objects, list) else []:
        if not isinstance(obj, dict) or obj.get("type") != "mesh":
            continue
        file = obj.get("file")
        if not isinstance(file, str) or not file:
            continue
        mesh_path = _join(folder, file)
        if not os.path.isfile(mesh_path):
            raise FileNotFoundError(2, "mesh file not found (objects[].file, relative to the scene file)", mesh_path)
        deps.append(file)
        mesh_folder = os.path.dirname(file)
        deps += [_join(mesh_folder, side) for side in _mesh_side_files(mesh_path)]
    return sorted(set(deps))


def scene_dependencies(scene: PathLike) -> list[str]:
    """The files the scene reads besides itself, as the C++ ``Scene::dependencies`` lists them:
    paths relative to the scene file's folder (as written in the scene, for a JSON scene's meshes),
    sorted, each once."""
    path = os.fspath(scene)
    if is_gltf_path(path):
        return _gltf_dependencies(path)
    return json_dependencies(path, read_scene_json(path))


def make_bundle(scene: PathLike, dependencies: Optional[list[str]] = None) -> Bundle:
    """The bundle of a scene file and its dependencies (default: ``scene_dependencies``), byte for
    byte what `tessera submit` uploads. FileNotFoundError names a file that cannot be read."""
    from .v1 import common_pb2  # generated at build time (python/CMakeLists.txt)

    path = os.fspath(scene)
    if dependencies is None:
        dependencies = scene_dependencies(path)
    scene_abs = _resolved(path)
    files = [scene_abs]
    for d in dependencies:
        # Two spellings of one file are one entry, as in the C++ client (lib/farm/bundle.cpp).
        f = _resolved(_join(os.path.dirname(scene_abs), d))
        if f not in files:
            files.append(f)
    # Deepest common directory of all files.
    root = os.path.dirname(scene_abs)
    for f in files:
        while root and root != os.path.dirname(root):
            rel = os.path.relpath(f, root)
            if rel.split(os.sep, 1)[0] != "..":
                break
            root = os.path.dirname(root)
    bundle = common_pb2.Bundle()
    names = []
    for i, f in enumerate(files):
        rel = _relative(f, root)
        if i == 0:
            bundle.scene_file = rel
        entry = bundle.files.add()
        entry.path = rel
        entry.content = _read(f, "scene file" if i == 0 else "file needed by the scene")
        names.append(rel)
    # Deterministic serialization, as the C++ client's: the same files give the same hash.
    data = bundle.SerializeToString(deterministic=True)
    return Bundle(data=data, sha256=hashlib.sha256(data).hexdigest(), scene_file=bundle.scene_file, files=names)
