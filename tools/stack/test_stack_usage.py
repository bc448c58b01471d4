#!/usr/bin/env python3
"""Self-test of tools/stack/stack_usage.py on a synthetic CMake build tree (no cross toolchain).

    test_stack_usage.py [-v]

The tree holds a library target CMakeFiles/magcal.dir whose link.txt lists two objects (their
.ci files: a public entry point of 64 B calling a helper of 96 B in the other unit: worst 160 B)
and an executable target whose link.txt lists its own object and another target's object
library. Checked: the worst cases through the call graph; that a stray .ci file below the
library's directory (a renamed source's leftover in an old build tree: a public function of
560 B, and a second definition of the helper's name) changes nothing; that DependInfo.cmake is
read when there is no link.txt; that an executable's --ci-dir reads its own objects only; that
an object without its .ci file is an error. Exit 0 when every check passes (CTest
stack_usage_objects).
"""
import io
import os
import sys
import tempfile
import unittest
from contextlib import redirect_stderr, redirect_stdout

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import stack_usage  # noqa: E402


def ci_text(src, nodes, edges):
    """A GCC -fcallgraph-info=su file: nodes (name, bytes) defined in src, edges (caller, callee)."""
    out = ['graph: { title: "%s"' % src]
    for i, (name, size) in enumerate(nodes):
        out.append('node: { title: "%s" label: "%s\\n%s:%d:5\\n%d bytes (static)" }' % (name, name, src, 10 + i, size))
    for a, b in edges:
        out.append('edge: { sourcename: "%s" targetname: "%s" label: "%s:20:5" }' % (a, b, src))
    out.append("}")
    return "\n".join(out) + "\n"


class StackUsageObjects(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        t = self.tmp.name
        self.src = os.path.join(t, "src_root")
        self.bld = os.path.join(t, "build")
        os.makedirs(os.path.join(self.src, "include", "magcal"))
        with open(os.path.join(self.src, "include", "magcal", "x.h"), "w") as f:
            f.write("int magcal_x_run(void);\nint magcal_x_gone(void);\nint magcal_x_probe(void);\n")
        self.lib = os.path.join(self.bld, "CMakeFiles", "magcal.dir")
        self.write("CMakeFiles/magcal.dir/src/a.c.ci",
                   ci_text("/s/src/a.c", [("magcal_x_run", 64)], [("magcal_x_run", "x_helper")]))
        self.write("CMakeFiles/magcal.dir/src/b.c.ci", ci_text("/s/src/b.c", [("x_helper", 96)], []))
        for o in ("src/a.c.obj", "src/b.c.obj"):
            self.write("CMakeFiles/magcal.dir/" + o, "")
        self.write("CMakeFiles/magcal.dir/link.txt",
                   "arm-none-eabi-ar qc libmagcal.a CMakeFiles/magcal.dir/src/a.c.obj "
                   "CMakeFiles/magcal.dir/src/b.c.obj\narm-none-eabi-ranlib libmagcal.a\n")
        # an executable: its own object (a probe calling the library) and another target's object
        self.exe = os.path.join(self.bld, "tests", "CMakeFiles", "probe.dir")
        self.write("tests/CMakeFiles/probe.dir/probe.c.ci",
                   ci_text("/s/tests/probe.c", [("probe_main", 40)], [("probe_main", "magcal_x_run")]))
        self.write("tests/CMakeFiles/probe.dir/probe.c.obj", "")
        self.write("tests/CMakeFiles/rt.dir/startup.c.ci", ci_text("/s/startup.c", [("x_helper", 900)], []))
        self.write("tests/CMakeFiles/probe.dir/link.txt",
                   "arm-none-eabi-gcc -Os CMakeFiles/probe.dir/probe.c.obj CMakeFiles/rt.dir/startup.c.obj "
                   "-o probe.elf ../libmagcal.a -lm\n")

    def tearDown(self):
        self.tmp.cleanup()

    def write(self, rel, text):
        p = os.path.join(self.bld, rel)
        os.makedirs(os.path.dirname(p), exist_ok=True)
        with open(p, "w") as f:
            f.write(text)

    def run_tool(self, *extra):
        out, err = io.StringIO(), io.StringIO()
        with redirect_stdout(out), redirect_stderr(err):
            try:
                rc = stack_usage.main(["stack_usage.py", self.bld, "--src-root", self.src, "--assume", ""] + list(extra))
            except SystemExit as e:
                rc = e.code if isinstance(e.code, int) else 1
                err.write(str(e.code))
        rows = {}
        for ln in out.getvalue().splitlines():
            f = ln.split()
            if len(f) >= 3 and f[1].isdigit() and f[2].isdigit():
                rows[f[0].lstrip("*")] = (int(f[1]), int(f[2]))
        return rc, rows, err.getvalue()

    def stray(self):
        self.write("CMakeFiles/magcal.dir/src/old/renamed.c.ci",
                   ci_text("/s/src/old/renamed.c", [("magcal_x_gone", 560), ("x_helper", 400)], []))

    def test_worst_case_through_the_call_graph(self):
        rc, rows, err = self.run_tool()
        self.assertEqual(rc, 0, err)
        self.assertEqual(rows["magcal_x_run"], (64, 160))
        self.assertEqual(rows["x_helper"], (96, 96))

    def test_stray_ci_file_changes_nothing(self):
        rc0, rows0, _ = self.run_tool()
        self.stray()
        rc1, rows1, err = self.run_tool()
        self.assertEqual((rc0, rc1), (0, 0), err)
        self.assertEqual(rows1, rows0)
        self.assertNotIn("magcal_x_gone", rows1)
        # the stray is there (the tool read every .ci below the directory before: its 560 B)
        every = sorted(os.path.relpath(os.path.join(d, n), self.lib) for d, _, fs in os.walk(self.lib)
                       for n in fs if n.endswith(".ci"))
        self.assertEqual(len(every), 3)

    def test_depend_info_when_no_link_txt(self):
        os.remove(os.path.join(self.lib, "link.txt"))
        self.write("CMakeFiles/magcal.dir/DependInfo.cmake",
                   'set(CMAKE_DEPENDS_DEPENDENCY_FILES\n'
                   '  "/s/src/a.c" "CMakeFiles/magcal.dir/src/a.c.obj" "gcc" "CMakeFiles/magcal.dir/src/a.c.obj.d"\n'
                   '  "/s/src/b.c" "CMakeFiles/magcal.dir/src/b.c.obj" "gcc" "CMakeFiles/magcal.dir/src/b.c.obj.d"\n'
                   '  )\n')
        self.stray()
        rc, rows, err = self.run_tool()
        self.assertEqual(rc, 0, err)
        self.assertEqual(rows["magcal_x_run"], (64, 160))
        self.assertNotIn("magcal_x_gone", rows)

    def test_ci_dir_reads_the_targets_own_objects(self):
        # probe_main is not a library function (not listed); its graph joins the library's, and the
        # object library's x_helper (900 B, another target's directory) is not read
        probe = os.path.join(self.src, "probe.sh")
        with open(probe, "w") as f:
            f.write("#!/bin/sh\necho 'STACK probe_main 150'\n")
        os.chmod(probe, 0o755)
        rc, rows, err = self.run_tool("--ci-dir", self.exe, "--measured-run", probe)
        self.assertEqual(rc, 0, err)
        self.assertEqual(rows["magcal_x_run"], (64, 160))
        self.assertEqual(rows["probe_main"], (150, 200))  # measured 150, static 40 + 160

    def test_object_without_its_ci_is_an_error(self):
        os.remove(os.path.join(self.lib, "src", "b.c.ci"))
        rc, _, err = self.run_tool()
        self.assertEqual(rc, 1)
        self.assertIn("no .ci file", err)


if __name__ == "__main__":
    unittest.main()
