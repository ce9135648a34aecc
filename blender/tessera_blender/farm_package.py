# SPDX-License-Identifier: Apache-2.0
"""Finds and imports Tessera's Python client package ``tessera``.

Where it looks, first match wins:
  1. the add-on preference "Tessera Python package" (a folder: the one holding ``tessera/``,
     e.g. ``build/python``, or the ``tessera`` package folder itself);
  2. the environment variable TESSERA_PYTHONPATH (the same kind of folder; several separated by
     os.pathsep);
  3. Blender's own sys.path (a ``tessera`` installed into Blender's Python, or the system's).
A package that is missing, or fails to import (e.g. grpc missing), is a FarmPackageError whose
message says what to set.
"""

import importlib
import os
import sys

ENV_VAR = "TESSERA_PYTHONPATH"


class FarmPackageError(Exception):
    pass


def _folder_holding_package(path):
    """The sys.path entry for PATH: its parent when PATH is the package folder itself."""
    path = os.path.abspath(os.path.expanduser(path))
    if os.path.basename(path.rstrip(os.sep)) == "tessera" and os.path.isfile(os.path.join(path, "__init__.py")):
        return os.path.dirname(path.rstrip(os.sep))
    return path


def candidate_folders(preference_path=""):
    folders = []
    if preference_path:
        folders.append(("the add-on preference", preference_path))
    for p in os.environ.get(ENV_VAR, "").split(os.pathsep):
        if p:
            folders.append((ENV_VAR, p))
    return folders


def _is_tessera_client(module):
    return all(hasattr(module, name) for name in ("Farm", "FarmError", "read_token_file"))


def import_tessera(preference_path=""):
    """The imported ``tessera`` client package, or FarmPackageError."""
    loaded = sys.modules.get("tessera")
    if loaded is not None and _is_tessera_client(loaded):
        return loaded
    notes = []
    for origin, path in candidate_folders(preference_path):
        entry = _folder_holding_package(bpy_abspath(path))
        if not os.path.isfile(os.path.join(entry, "tessera", "__init__.py")):
            notes.append(f"{origin}: {entry} has no tessera/__init__.py")
            continue
        if entry not in sys.path:
            sys.path.insert(0, entry)
        return _import(f"{origin} ({entry})")
    try:
        return _import("Blender's sys.path")
    except _NotFound:
        pass
    raise FarmPackageError(
        "Tessera's Python package 'tessera' was not found" + (" (" + "; ".join(notes) + ")" if notes else "") +
        ". Set its folder (e.g. tessera/build/python) in Edit > Preferences > Add-ons > Tessera render farm, "
        f"or the environment variable {ENV_VAR}")


class _NotFound(FarmPackageError):
    pass


def _import(origin):
    stale = sys.modules.get("tessera")
    if stale is not None and not _is_tessera_client(stale):
        del sys.modules["tessera"]
    try:
        module = importlib.import_module("tessera")
    except ModuleNotFoundError as e:
        if e.name == "tessera":
            raise _NotFound(f"not found on {origin}") from None
        raise FarmPackageError(f"importing 'tessera' from {origin} failed: {e}") from None
    except Exception as e:  # a broken install: say so, never a traceback
        raise FarmPackageError(f"importing 'tessera' from {origin} failed: {type(e).__name__}: {e}") from None
    if not _is_tessera_client(module):
        where = getattr(module, "__file__", None) or origin
        del sys.modules["tessera"]
        raise FarmPackageError(f"the module 'tessera' at {where} is not Tessera's client package (it has no Farm)")
    return module


def bpy_abspath(path):
    """Blender-relative ('//') paths resolved against the .blend file; others unchanged."""
    try:
        import bpy

        return bpy.path.abspath(path)
    except ImportError:
        return path
