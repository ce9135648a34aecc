#!/usr/bin/env python3
"""Checks the rules of docs/architecture.md that a reader could break without noticing.

- Rooms: which product folders may include which headers (server/ never reaches lib/render,
  lib/tile nothing of Embree or gRPC, lib/color no command-line parsing, lib/rays no gRPC, nothing
  outside lib/render the RenderScene's internals; lib/farm and lib/rays throw their own exception
  classes), and, when a build folder is given, that the programs' link lines agree
  (tessera-server links no renderer or Embree; tessera-rays no coordinator or worker library).
- Programs' includes and links: an include of a program's file resolves as its build finds it
  (beside the file, the program's own folder, lib/, proto/) and must not land in another
  program's folder; no program's executable links a library defined under another program's
  folder. "rays/ray_check.h" is lib/rays; the ray server's own headers are included bare.
- Size: no product source file over 700 lines, no function over 150 lines.
- No tracker numbers: no source, test, doc or script cites the issue tracker by number
  (tracker_citations.py says which forms count).

Usage: check_layout.py SOURCE_DIR [BUILD_DIR]. Prints every breach and exits 1 if there is one.
"""
import os
import re
import sys

from tracker_citations import tracker_citations

MAX_FILE_LINES = 700
MAX_FUNCTION_LINES = 150
PRODUCT_ROOMS = ["lib", "server", "worker", "client", "rays"]
# Each program's folder and its executable's path in the build folder.
PROGRAMS = {"server": "server/tessera-server", "worker": "worker/tessera-worker", "client": "client/tessera",
            "rays": "rays/tessera-rays"}

# (room prefix, regex of a forbidden #include target, why). A program's includes of another
# program's code are found by where they land, not by name (program_include_breaches).
INCLUDE_RULES = [
    ("server/", r'^render/|^embree3/|^rays/', "the coordinator must not reach the renderer"),
    ("server/monitor/", r'^(coordinator|job_store|client_service|worker_service)\.h$',
     "the monitor reads the farm through farm_view.h (and farm_control.h), not the coordinator itself"),
    ("server/metrics/", r'^(coordinator|job_store|client_service|worker_service)\.h$',
     "the metrics read the farm through farm_view.h, not the coordinator itself"),
    ("lib/tile/", r'^(render|farm|scene|color|rays)/|^embree3/|^grpcpp/|^Imf|^OpenEXR/',
     "tiles are plain values: no renderer, no wire, no OpenEXR"),
    ("lib/color/", r'^CLI/', "command-line parsing belongs to the programs"),
    ("lib/render/", r'^(farm|color|rays)/|^grpcpp/', "the renderer knows nothing of the farm"),
    ("lib/scene/", r'^(render|farm|color|rays|tile)/|^embree3/|^grpcpp/', "scenes are plain data"),
    ("lib/sampling/", r'^(render|farm|color|rays)/|^embree3/|^grpcpp/',
     "where samples go is plain arithmetic the coordinator shares: no renderer, no wire"),
    ("lib/farm/", r'^(rays|color)/', "the shared room holds what the programs share on the wire"),
    ("lib/rays/", r'^(farm|color)/|^grpcpp/', "ray queries know nothing of the farm or gRPC (the codec speaks "
     "messages only)"),
]
# Only these files of lib/farm may include the renderer: the bundle cache of render scenes.
FARM_RENDER_FILES = {"lib/farm/bundle_cache.h", "lib/farm/bundle_cache.cpp"}
# Every product C++ file says its license on its first line (LICENSE; CONTRIBUTING.md).
SPDX_LINE = "// SPDX-License-Identifier: Apache-2.0\n"
# lib/render's own headers: the whole RenderScene (its packet and ISA-cloned internals) and its
# Embree side. Everyone else sees a RenderScene through render/render_scene.h.
RENDER_INTERNAL = r'^render/render_scene_(internal|embree)\.h$'
# Rooms that throw their own exception class (docs/architecture.md, "Errors"), never a bare
# standard one: lib/farm's FarmError, lib/rays' RaysError.
OWN_ERROR_ROOMS = {"lib/farm/": "farm::FarmError", "lib/rays/": "rays::RaysError"}
BARE_THROW = re.compile(r'\bthrow\s+std::(runtime_error|invalid_argument|logic_error|exception)\b')


# (executable's path in the build folder, forbidden library regex)
LINK_RULES = [
    ("server/tessera-server",
     r'libtessera_render\.a|libtessera_bundle_cache\.a|libtessera_rays\.a|libembree|libtessera_worker_core\.a'),
    ("rays/tessera-rays",
     r'libtessera_coordinator\.a|libtessera_scheduler\.a|libtessera_job_store\.a|libtessera_worker_core\.a'),
    ("worker/tessera-worker", r'libtessera_coordinator\.a|libtessera_scheduler\.a|libtessera_job_store\.a'),
]


def link_line(build, exe):
    """The libraries `exe` links, from the generator's own files: link.txt (Makefiles) or the
    executable's build statement in build.ninja (Ninja). None when neither is there."""
    name = os.path.basename(exe)
    txt = os.path.join(build, os.path.dirname(exe), "CMakeFiles", name + ".dir", "link.txt")
    if os.path.exists(txt):
        with open(txt) as f:
            return f.read()
    ninja = os.path.join(build, "build.ninja")
    if not os.path.exists(ninja):
        return None
    with open(ninja) as f:
        text = f.read()
    m = re.search(r'^build ' + re.escape(exe) + r':.*?(?=\n\n)', text, flags=re.S | re.M)
    return m.group(0) if m else None

INCLUDE = re.compile(r'^\s*#\s*include\s*([<"])([^">]+)[">]')  # the delimiter, then the path


def product_files(src):
    for room in PRODUCT_ROOMS:
        for root, _, files in os.walk(os.path.join(src, room)):
            for f in sorted(files):
                if not f.endswith((".cpp", ".h")) or f.endswith("_test.cpp"):
                    continue
                path = os.path.join(root, f)
                yield os.path.relpath(path, src), path


def strip_code(text):
    """Comments, strings and character literals blanked, line breaks kept."""
    out, i, n = [], 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("//", i):
            j = text.find("\n", i)
            j = n if j < 0 else j
            i = j
        elif text.startswith("/*", i):
            j = text.find("*/", i + 2)
            j = n if j < 0 else j + 2
            out.append("\n" * text.count("\n", i, j))
            i = j
        elif text.startswith('R"', i):
            m = re.match(r'R"([^(]*)\(', text[i:])
            if m:
                end = text.find(")" + m.group(1) + '"', i)
                end = n if end < 0 else end + len(m.group(1)) + 2
                out.append('""' + "\n" * text.count("\n", i, end))
                i = end
            else:
                out.append(c)
                i += 1
        elif c in "\"'":
            j = i + 1
            while j < n and text[j] != c:
                j += 2 if text[j] == "\\" else 1
            out.append(c + c)
            i = j + 1
        else:
            out.append(c)
            i += 1
    return "".join(out)


def long_functions(text):
    """(first line, lines) of each function body longer than the limit. A function is a brace block
    opened outside any other function whose head has a parameter list and is not a type, namespace
    or initializer."""
    code = strip_code(text)
    found = []
    stack = []  # for each open brace: is it a function body, its start line
    head_start = 0
    line = 1
    in_function = 0
    for i, c in enumerate(code):
        if c == "\n":
            line += 1
        elif c == "{":
            head = code[head_start:i]
            is_function = False
            if in_function == 0:
                h = " ".join(head.split())
                is_type = re.search(r'\b(namespace|class|struct|union|enum)\b[^()]*$', h) is not None
                is_function = "(" in h and not is_type and not h.rstrip().endswith("=") and \
                    re.search(r'\)\s*(const|noexcept|override|final|->[^{]*|mutable|\s)*\s*$|\)\s*:.*\)\s*$', h) is not None
            stack.append((is_function, line))
            if is_function:
                in_function += 1
            head_start = i + 1
        elif c == "}":
            if stack:
                is_function, start = stack.pop()
                if is_function:
                    in_function -= 1
                    if line - start + 1 > MAX_FUNCTION_LINES:
                        found.append((start, line - start + 1))
            head_start = i + 1
        elif c == ";" and in_function == 0:
            head_start = i + 1
    return found


def reaches(src, rel, forbidden_prefix, seen=None):
    """The chain of project headers by which `rel` includes a file under `forbidden_prefix`, or
    None. Quoted includes resolve against the file's folder, its room (server/, ...) and lib/."""
    seen = set() if seen is None else seen
    with open(os.path.join(src, rel), encoding="utf-8", errors="replace") as f:
        text = f.read()
    room = rel.split("/")[0]
    for l in text.splitlines():
        m = re.match(r'^\s*#\s*include\s*"([^"]+)"', l)
        if not m:
            continue
        for base in (os.path.dirname(rel), room, "lib", "proto"):
            cand = os.path.normpath(os.path.join(base, m.group(1)))
            if os.path.isfile(os.path.join(src, cand)):
                break
        else:
            continue  # generated or system header
        if cand.startswith(forbidden_prefix):
            return [cand]
        if cand in seen:
            continue
        seen.add(cand)
        chain = reaches(src, cand, forbidden_prefix, seen)
        if chain:
            return [cand] + chain
    return None


def program_dirs(src, program):
    """The program's folder and every folder under it, relative to `src`."""
    return [os.path.relpath(root, src) for root, _, _ in sorted(os.walk(os.path.join(src, program)))]


def resolve_include(src, rel, target, quoted, dirs):
    """The file, relative to `src`, that an #include of program file `rel` names: beside `rel`
    (quoted only), in its program's own folders, in lib/, in proto/, as the build finds it. Failing
    those, where it would land if another program's folder (or the source folder itself) were on
    the include path: that is a breach the caller reports. None for a system, third-party or
    generated header."""
    program = rel.split("/")[0]
    here = [os.path.dirname(rel)] if quoted else []
    others = [d for p in PROGRAMS if p != program for d in dirs[p]]
    for base in here + dirs[program] + ["lib", "proto", "."] + others:
        cand = os.path.normpath(os.path.join(base, target))
        if os.path.isfile(os.path.join(src, cand)):
            return cand
    return None


def program_include_breaches(src):
    """Every include of a program's file (its tests too) that lands in another program's folder."""
    dirs = {p: program_dirs(src, p) for p in PROGRAMS}
    breaches = []
    for program in PROGRAMS:
        for root, _, files in sorted(os.walk(os.path.join(src, program))):
            for f in sorted(files):
                if not f.endswith((".cpp", ".h")):
                    continue
                rel = os.path.relpath(os.path.join(root, f), src)
                with open(os.path.join(src, rel), encoding="utf-8", errors="replace") as fh:
                    lines = fh.read().splitlines()
                for k, l in enumerate(lines, 1):
                    m = INCLUDE.match(l)
                    if not m:
                        continue
                    found = resolve_include(src, rel, m.group(2), m.group(1) == '"', dirs)
                    owner = found.split("/")[0] if found else None
                    if owner in PROGRAMS and owner != program:
                        breaches.append(f"{rel}:{k}: includes {m.group(2)}, which is {found}: programs share code "
                                        "only through lib/")
    return breaches


def program_libraries(src, program):
    """The libraries the CMake files under a program's folder define."""
    names = set()
    for root, _, files in os.walk(os.path.join(src, program)):
        if "CMakeLists.txt" in files:
            with open(os.path.join(root, "CMakeLists.txt")) as f:
                names.update(re.findall(r'add_library\(\s*([A-Za-z0-9_]+)', f.read()))
    return names


def program_link_breaches(src, build):
    """Each program executable linking a library that another program's folder defines."""
    breaches = []
    for program, exe in PROGRAMS.items():
        line = link_line(build, exe)
        if line is None:
            continue  # said by the link rules below
        for other in PROGRAMS:
            if other == program:
                continue
            for lib in sorted(program_libraries(src, other)):
                if re.search(r'(^|[/\s])lib' + re.escape(lib) + r'\.a\b', line):
                    breaches.append(f"{exe} links lib{lib}.a, a library of {other}/: programs share code only "
                                    "through lib/")
    return breaches


def main():
    src = sys.argv[1]
    build = sys.argv[2] if len(sys.argv) > 2 else None
    breaches = []
    for rel, path in product_files(src):
        with open(path, encoding="utf-8", errors="replace") as f:
            text = f.read()
        if not text.startswith(SPDX_LINE):
            breaches.append(f"{rel}:1: does not start with '{SPDX_LINE.strip()}' (the project is Apache-2.0)")
        lines = text.count("\n")
        if lines > MAX_FILE_LINES:
            breaches.append(f"{rel}: {lines} lines, over {MAX_FILE_LINES}: split it by concept")
        for start, n in long_functions(text):
            breaches.append(f"{rel}:{start}: a function of {n} lines, over {MAX_FUNCTION_LINES}")
        for k, l in enumerate(text.splitlines(), 1):
            m = INCLUDE.match(l)
            if not m:
                continue
            target = m.group(2)
            for room, pattern, why in INCLUDE_RULES:
                if rel.startswith(room) and re.search(pattern, target):
                    breaches.append(f"{rel}:{k}: includes {target}: {why}")
            if rel.startswith("lib/farm/") and rel not in FARM_RENDER_FILES and re.search(r'^render/|^embree3/', target):
                breaches.append(f"{rel}:{k}: includes {target}: only the bundle cache of lib/farm may use the renderer")
            if not rel.startswith("lib/render/") and re.search(RENDER_INTERNAL, target):
                breaches.append(f"{rel}:{k}: includes {target}, lib/render's own: use render/render_scene.h")
        for room, cls in OWN_ERROR_ROOMS.items():
            if rel.startswith(room):
                for k, l in enumerate(strip_code(text).splitlines(), 1):
                    if BARE_THROW.search(l):
                        breaches.append(f"{rel}:{k}: throws a bare std:: exception: {room} throws {cls}")
        if rel.startswith("server/"):
            chain = reaches(src, rel, "lib/render/")
            if chain:
                breaches.append(f"{rel}: reaches the renderer through {' -> '.join(chain)}")
    breaches += program_include_breaches(src)
    breaches += tracker_citations(src)
    if build:
        breaches += program_link_breaches(src, build)
        for exe, pattern in LINK_RULES:
            line = link_line(build, exe)
            if line is None:
                breaches.append(f"{exe}: no link line in {build} (configure it first)")
                continue
            bad = sorted(set(re.findall(pattern, line)))
            if bad:
                breaches.append(f"{exe} links {', '.join(bad)}")
    for b in breaches:
        print(b)
    checked = sum(1 for _ in product_files(src))
    print(f"check_layout: {checked} product files, {len(breaches)} breaches")
    return 1 if breaches else 0


if __name__ == "__main__":
    sys.exit(main())
