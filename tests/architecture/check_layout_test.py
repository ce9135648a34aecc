#!/usr/bin/env python3
"""check_layout.py seen to fail: a small tree with one planted breach of each rule it was given
for programs, for the rooms' own exceptions and for tracker numbers makes it exit 1 naming each,
and the same tree without them (but with what only looks like a breach) passes.

Usage: check_layout_test.py (run by ctest -L architecture).
"""
import os
import subprocess
import sys
import tempfile
import unittest

CHECKER = os.path.join(os.path.dirname(os.path.abspath(__file__)), "check_layout.py")
# Built from parts, so that this file does not cite the tracker itself.
CITATION_WORD = "iss" + "ue 42"
CITATION_HASH = "see " + "#" + "42"

PROGRAM_EXECUTABLES = ["server/tessera-server", "worker/tessera-worker", "client/tessera", "rays/tessera-rays"]


SPDX = "// SPDX-License-Identifier: Apache-2.0\n"


def write(root, rel, text):
    path = os.path.join(root, rel)
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "w") as f:
        f.write(text)


def write_clean(root, rel, text):
    """As write(), the SPDX line first in a C++ file: what a file that keeps every rule has."""
    write(root, rel, SPDX + text if rel.endswith((".h", ".cpp")) else text)


def clean_tree(src, build):
    """A tree that keeps every rule, with things that only look like breaches."""

    write_clean(src, "lib/farm/channel.h", "#pragma once\n")
    write_clean(src, "lib/rays/ray_check.h", "#pragma once\n")
    write_clean(src, "lib/rays/ray_codec.h", '#pragma once\n#include "rays/ray_check.h"\n')
    write_clean(src, "lib/rays/CMakeLists.txt", "add_library(tessera_ray_codec STATIC ray_codec.cpp)\n")
    write_clean(src, "rays/ray_service.h", '#pragma once\n#include "farm/channel.h"\n')
    # The ray server's own header bare, lib/rays' by its room.
    write_clean(src, "rays/ray_service.cpp", '#include "ray_service.h"\n#include "rays/ray_codec.h"\n')
    write_clean(src, "rays/CMakeLists.txt", "add_library(tessera_ray_server STATIC ray_service.cpp)\n")
    write_clean(src, "client/rays_command.cpp",
          '#include <string>\n#include "farm/channel.h"\n#include "rays/ray_codec.h"\n'
          '#include "tessera/v1/ray_service.pb.h"\n// frame #3 of the job, colour #000\n')
    write_clean(src, "server/monitor/web/monitor.css", "#identity { color: #667; background: #000; }\n")
    write_clean(src, "docs/notes.md", "# Notes\n\nSee [part 3](#3-a-title); the 2nd run, step 4.\n")
    for exe in PROGRAM_EXECUTABLES:
        write(build, os.path.join(os.path.dirname(exe), "CMakeFiles", os.path.basename(exe) + ".dir", "link.txt"),
              "c++ main.o -o " + exe + " lib/farm/libtessera_farm.a lib/rays/libtessera_ray_codec.a\n")


def run_checker(src, build):
    r = subprocess.run([sys.executable, CHECKER, src, build], capture_output=True, text=True)
    return r.returncode, r.stdout + r.stderr


class CheckLayoutTest(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.src = os.path.join(self.tmp.name, "src")
        self.build = os.path.join(self.tmp.name, "build")
        clean_tree(self.src, self.build)

    def tearDown(self):
        self.tmp.cleanup()

    def test_a_clean_tree_passes(self):
        code, out = run_checker(self.src, self.build)
        self.assertEqual(code, 0, out)

    def test_a_program_including_another_programs_header_fails(self):
        # Bare, as the CLI would find it were rays/ on its include path; and rooted, as if
        # "rays/" named the program.
        write(self.src, "client/rays_command.cpp", '#include "farm/channel.h"\n#include "ray_service.h"\n')
        write(self.src, "worker/connection.cpp", '#include "rays/ray_service.h"\n')
        code, out = run_checker(self.src, self.build)
        self.assertEqual(code, 1, out)
        self.assertIn("client/rays_command.cpp:2: includes ray_service.h, which is rays/ray_service.h", out)
        self.assertIn("worker/connection.cpp:1: includes rays/ray_service.h, which is rays/ray_service.h", out)

    def test_the_cli_linking_a_library_of_another_program_fails(self):
        write(self.build, "client/CMakeFiles/tessera.dir/link.txt",
              "c++ main.o -o client/tessera lib/farm/libtessera_farm.a rays/libtessera_ray_server.a\n")
        code, out = run_checker(self.src, self.build)
        self.assertEqual(code, 1, out)
        self.assertIn("client/tessera links libtessera_ray_server.a, a library of rays/", out)

    def test_a_bare_standard_exception_in_lib_rays_fails(self):
        write(self.src, "lib/rays/ray_csv.cpp", 'void f() {\n  throw std::runtime_error("bad");\n}\n')
        code, out = run_checker(self.src, self.build)
        self.assertEqual(code, 1, out)
        self.assertIn("lib/rays/ray_csv.cpp:2: throws a bare std:: exception: lib/rays/ throws rays::RaysError", out)

    def test_a_product_file_without_the_spdx_line_fails(self):
        write(self.src, "lib/farm/channel.h", "#pragma once\n")
        code, out = run_checker(self.src, self.build)
        self.assertEqual(code, 1, out)
        self.assertIn("lib/farm/channel.h:1: does not start with '// SPDX-License-Identifier: Apache-2.0'", out)

    def test_a_tracker_number_fails(self):
        write(self.src, "docs/notes.md", f"# Notes\n\nFixed the leak ({CITATION_WORD}).\n")
        write(self.src, "lib/farm/channel.cpp", f"// The retry below: {CITATION_HASH}.\nint x;\n")
        write(self.src, "scripts/run.sh", f"#!/bin/sh\n# ({CITATION_HASH.split()[1]})\n")
        code, out = run_checker(self.src, self.build)
        self.assertEqual(code, 1, out)
        self.assertIn("docs/notes.md:3: cites the tracker by number", out)
        self.assertIn("lib/farm/channel.cpp:1: cites the tracker by number", out)
        self.assertIn("scripts/run.sh:2: cites the tracker by number", out)


if __name__ == "__main__":
    unittest.main()
