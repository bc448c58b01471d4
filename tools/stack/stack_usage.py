#!/usr/bin/env python3
"""Worst-case stack depth of every libmagcal function, through the call graph.

    stack_usage.py BUILD_DIR [--limit BYTES] [--public-only] [--src-root DIR]

Reads the GCC -fstack-usage (.su) and -fcallgraph-info=su (.ci) files that the Cortex-M4F
toolchain file (cmake/toolchain-cortex-m4f.cmake) writes next to libmagcal's objects
(BUILD_DIR/CMakeFiles/magcal.dir/**): only those of the objects the target links, as CMake lists
them (the target's link.txt, else its DependInfo.cmake), so a .ci file left behind by a renamed
or deleted source in an old build tree is never read (one gave a false 560-B worst case). The worst case of a function is its own frame plus the
largest worst case among its callees; the library has no recursion, so this is exact for the
library's own code (up to interrupts, which the caller's budget must add).

Calls that leave the library (libm: sqrtf, fmodf, atan2f, ...) are costed from the newlib
archives of the same multilib: the prologue of each function in `objdump -dr` (push, vpush,
sub sp) plus, recursively, its callees found through R_ARM_THM_CALL/JUMP24 relocations.

Assumptions (--assume, default tools/stack/assumptions.txt): `caller callee  # reason` lines
remove call edges that the library's arguments provably never take (e.g. libm's huge-argument
range reduction); each needs its reason, and the table marks pruned paths.

Calls into the HAL port (functions declared in port/magcal_port.h) are the firmware's code: they
count as 0 bytes and are listed, so the integrator adds the port's own worst case.

Errors (exit 1): a cycle in the call graph, a dynamic or dynamic,bounded frame, an indirect
call, an external function that cannot be costed, or (with --limit) a public entry point whose
worst case exceeds the limit. Standard library only (plus arm-none-eabi-objdump / -gcc).
"""
import argparse
import glob
import os
import re
import subprocess
import sys

M4F_FLAGS = ["-mcpu=cortex-m4", "-mthumb", "-mfloat-abi=hard", "-mfpu=fpv4-sp-d16"]
NODE_RE = re.compile(r'node: \{ title: "([^"]+)" label: "([^"]*)"')
EDGE_RE = re.compile(r'edge: \{ sourcename: "([^"]+)" targetname: "([^"]+)"')
FRAME_RE = re.compile(r"\\n(\d+) bytes \(([^)]+)\)")
REG_LIST_RE = re.compile(r"\{([^}]*)\}")


class Graph:
    def __init__(self):
        self.frame = {}  # name -> bytes (library functions)
        self.kind = {}  # name -> static/dynamic/...
        self.where = {}  # name -> file:line
        self.calls = {}  # name -> set of callee names
        self.external = set()


OBJ_RE = re.compile(r"\.(?:c|cc|cpp|cxx|s|S)\.(?:obj|o)$")
DEP_RE = re.compile(r'^\s*"[^"]+"\s+"([^"]+)"\s+"[^"]*"\s+"[^"]*"\s*$')


def target_objects(target_dir):
    """Object files (absolute) the CMake target whose CMakeFiles/<name>.dir is target_dir builds
    and links, from its link.txt (Makefile generators: the archiver's or linker's command line),
    else from its DependInfo.cmake (source, object, compiler, depfile quadruples); only the
    objects inside target_dir (not another target's object library). None when the directory
    has neither file (not a CMake target directory)."""
    base = os.path.dirname(os.path.dirname(os.path.abspath(target_dir)))  # the target's binary dir
    objs = []
    link = os.path.join(target_dir, "link.txt")
    dep = os.path.join(target_dir, "DependInfo.cmake")
    if os.path.exists(link):
        with open(link) as f:
            for tok in f.read().split():
                if OBJ_RE.search(tok):
                    objs.append(tok)
    elif os.path.exists(dep):
        with open(dep) as f:
            for line in f:
                m = DEP_RE.match(line)
                if m and OBJ_RE.search(m.group(1)):
                    objs.append(m.group(1))
    else:
        return None
    root = os.path.abspath(target_dir) + os.sep
    out = []
    for o in objs:
        a = os.path.normpath(o if os.path.isabs(o) else os.path.join(base, o))
        if a.startswith(root) and a not in out:
            out.append(a)
    return out


def target_cis(target_dir, what):
    """The .ci files of target_dir's objects (GCC writes <object minus its last suffix>.ci next
    to each object); exits when an object has none. A directory that is not a CMake target
    directory: every .ci below it (a warning)."""
    objs = target_objects(target_dir)
    if objs is None:
        print("stack_usage: WARNING: %s has no link.txt / DependInfo.cmake: reading every .ci below it"
              % target_dir, file=sys.stderr)
        return sorted(glob.glob(os.path.join(target_dir, "**", "*.ci"), recursive=True))
    if not objs:
        sys.exit("stack_usage: %s lists no objects (%s)" % (target_dir, what))
    cis = []
    missing = []
    for o in objs:
        ci = os.path.splitext(o)[0] + ".ci"
        (cis if os.path.exists(ci) else missing).append(ci)
    if missing:
        sys.exit("stack_usage: no .ci file for %d object(s) of %s, e.g. %s (build with "
                 "cmake/toolchain-cortex-m4f.cmake)" % (len(missing), what, missing[0]))
    return sorted(cis)


def load_library(build_dir, extra_dirs=()):
    g = Graph()
    root = os.path.join(build_dir, "CMakeFiles", "magcal.dir")
    if not os.path.isdir(root):
        sys.exit("stack_usage: no %s (build with cmake/toolchain-cortex-m4f.cmake)" % root)
    cis = target_cis(root, "the library")
    if not cis:
        sys.exit("stack_usage: no .ci files under %s (build with cmake/toolchain-cortex-m4f.cmake)" % root)
    g.library = set()
    lib_root = os.path.abspath(root) + os.sep
    for d in extra_dirs:
        cis += target_cis(d, d)
    for ci in cis:
        in_lib = os.path.abspath(ci).startswith(lib_root)
        local_defs = {}
        edges = []
        with open(ci) as f:
            for line in f:
                m = NODE_RE.search(line)
                if m:
                    title, label = m.group(1), m.group(2)
                    fm = FRAME_RE.search(label)
                    if fm:  # defined in this unit (external nodes carry no frame)
                        name = title.split(":")[-1]
                        if name in g.frame:
                            # two static functions with one name: keep them apart
                            name = "%s:%s" % (os.path.basename(ci)[:-3], name)
                        local_defs[title] = name
                        g.frame[name] = int(fm.group(1))
                        g.kind[name] = fm.group(2)
                        g.where[name] = label.split("\\n")[1] if "\\n" in label else ci
                        g.calls.setdefault(name, set())
                        if in_lib:
                            g.library.add(name)
                    continue
                m = EDGE_RE.search(line)
                if m:
                    edges.append((m.group(1), m.group(2)))
        for src, dst in edges:
            if ":" in dst and dst not in local_defs:
                # a static function of this unit with no node of its own: GCC inlined it into
                # every caller, so its frame and its calls are already in the callers'
                continue
            s = local_defs.get(src, src.split(":")[-1])
            d = local_defs.get(dst, dst.split(":")[-1])
            g.calls.setdefault(s, set()).add(d)
    for callees in list(g.calls.values()):
        for c in callees:
            if c not in g.frame:
                g.external.add(c)
    return g


def parse_objdump(text):
    """function -> (frame bytes from the prologue, set of called symbols)."""
    funcs = {}
    cur = None
    for line in text.splitlines():
        m = re.match(r"^[0-9a-f]+ <([^>]+)>:$", line)
        if m:
            cur = m.group(1)
            funcs[cur] = [0, set(), True]  # frame, callees, still in prologue
            continue
        if cur is None:
            continue
        rel = re.search(r"R_ARM_THM_(?:CALL|JUMP24)\s+(\S+)", line)
        if rel:
            funcs[cur][1].add(rel.group(1).split("+")[0])
            continue
        ins = line.split("\t")
        if len(ins) < 2:
            continue
        op = ins[1].strip()
        args = ins[2] if len(ins) > 2 else ""
        if op.startswith("push") or op.startswith("stmdb") and "sp!" in args:
            regs = REG_LIST_RE.search(args)
            if regs:
                funcs[cur][0] += 4 * len(expand_regs(regs.group(1)))
        elif op.startswith("vpush"):
            regs = REG_LIST_RE.search(args)
            if regs:
                n = len(expand_regs(regs.group(1)))
                funcs[cur][0] += n * (8 if "d" in regs.group(1) else 4)
        elif (op.startswith("sub") and args.startswith("sp,")) or op.startswith("subw") and args.startswith("sp,"):
            num = re.search(r"#(\d+)", args)
            if num:
                funcs[cur][0] += int(num.group(1))
            else:
                funcs[cur][0] = None  # sp adjusted by a register: dynamic
    return {k: (v[0], v[1]) for k, v in funcs.items()}


def expand_regs(spec):
    out = []
    for part in spec.split(","):
        part = part.strip()
        m = re.match(r"([a-z]+)(\d+)-[a-z]+(\d+)$", part)
        if m:
            out += ["%s%d" % (m.group(1), i) for i in range(int(m.group(2)), int(m.group(3)) + 1)]
        elif part:
            out.append(part)
    return out


def load_newlib():
    funcs = {}
    for lib in ("libm.a", "libc.a"):
        path = subprocess.run(["arm-none-eabi-gcc"] + M4F_FLAGS + ["-print-file-name=" + lib],
                              capture_output=True, text=True, check=True).stdout.strip()
        text = subprocess.run(["arm-none-eabi-objdump", "-dr", "--no-show-raw-insn", path],
                              capture_output=True, text=True, check=True).stdout
        for k, v in parse_objdump(text).items():
            funcs.setdefault(k, v)
    return funcs


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("build_dir")
    ap.add_argument("--limit", type=int, default=0, help="fail if a public entry point needs more (bytes)")
    ap.add_argument("--budgets", default="",
                    help="per-function budget table (tools/stack/budgets.txt): fail if a public entry "
                         "point needs more than its budget (or the table's `default`)")
    ap.add_argument("--public-only", action="store_true", help="list only functions declared in include/")
    ap.add_argument("--src-root", default=os.path.join(os.path.dirname(__file__), "..", ".."))
    ap.add_argument("--assume", default=os.path.join(os.path.dirname(__file__), "assumptions.txt"))
    ap.add_argument("--ci-dir", action="append", default=[],
                    help="also read the .ci files of this CMake target directory's objects (e.g. "
                         "CMakeFiles/stack_watermark.dir; a plain directory: every .ci below it)")
    ap.add_argument("--measured-run", nargs=argparse.REMAINDER,
                    help="run this command (last option); its `STACK fn bytes` lines must not exceed "
                         "the static worst case of fn")
    args = ap.parse_args(argv[1:])

    g = load_library(args.build_dir, args.ci_dir)
    errors = []
    ext = load_newlib() if g.external else {}
    pruned = set()
    if args.assume and os.path.exists(args.assume):
        with open(args.assume) as f:
            for ln in f:
                body, _, reason = ln.partition("#")
                parts = body.split()
                if not parts:
                    continue
                if len(parts) != 2 or not reason.strip():
                    sys.exit("stack_usage: bad assumption line (need `caller callee # reason`): " + ln)
                pruned.add((parts[0], parts[1]))
    for caller, callee in pruned:
        if caller in ext and callee in ext[caller][1]:
            ext[caller][1].discard(callee)
        elif callee in g.calls.get(caller, set()):
            g.calls[caller].discard(callee)

    public = set()
    for h in glob.glob(os.path.join(args.src_root, "include", "**", "*.h"), recursive=True):
        with open(h) as f:
            public.update(re.findall(r"\b(magcal_[a-z0-9_]+)\s*\(", f.read()))

    # The HAL port (port/magcal_port.h) is implemented by the firmware: its frames are not
    # known here and count as 0; the caller adds its port's worst case (reported below).
    port = set()
    port_h = os.path.join(args.src_root, "port", "magcal_port.h")
    if os.path.exists(port_h):
        with open(port_h) as f:
            port.update(re.findall(r"\b(magcal_port_[a-z0-9_]+)\s*\(", f.read()))
    port_used = set()

    memo = {}
    onstack = []

    def worst(name, depth=0):
        """(bytes, path) of the deepest chain from name."""
        if name in memo:
            return memo[name]
        if name in onstack:
            errors.append("cycle: " + " -> ".join(onstack[onstack.index(name):] + [name]))
            return (0, [name])
        if depth > 64:
            errors.append("call chain deeper than 64 at %s" % name)
            return (0, [name])
        onstack.append(name)
        if name in g.frame:
            own = g.frame[name]
            if g.kind[name] != "static":
                errors.append("%s: %s frame (%s)" % (name, g.kind[name], g.where[name]))
            callees = g.calls.get(name, set())
        elif name in port:
            port_used.add(name)
            own, callees = 0, set()
        elif name in ext:
            own, callees = ext[name]
            if own is None:
                errors.append("%s (newlib): stack pointer moved by a register" % name)
                own = 0
        else:
            if name == "__indirect_call" or name.startswith("*"):
                errors.append("indirect call (unbounded callee)")
            else:
                errors.append("%s: external function not found in newlib, cannot cost it" % name)
            own, callees = 0, set()
        best = (0, [])
        for c in sorted(callees):
            r = worst(c, depth + 1)
            if r[0] > best[0]:
                best = r
        onstack.pop()
        memo[name] = (own + best[0], [name] + best[1])
        return memo[name]

    rows = []
    for name in sorted(g.library):
        if args.public_only and name not in public:
            continue
        total, path = worst(name)
        rows.append((name, g.frame[name], total, name in public, path))

    w = max([len(r[0]) for r in rows] + [8])
    print("%-*s %6s %7s  %s" % (w, "function", "own", "worst", "deepest path (public API marked *)"))
    for name, own, total, pub, path in rows:
        print("%-*s %6d %7d  %s" % (w, ("*" if pub else " ") + name, own, total, " -> ".join(path)))
    if args.limit:
        for name, _, total, pub, _ in rows:
            if pub and total > args.limit:
                errors.append("%s needs %d bytes > limit %d" % (name, total, args.limit))
        pubs = [r for r in rows if r[3]]
        if pubs:
            top = max(pubs, key=lambda r: r[2])
            print("worst public entry point: %s, %d bytes (limit %d)" % (top[0], top[2], args.limit))
    if args.budgets:
        budget = {}
        with open(args.budgets) as f:
            for line in f:
                fields = line.split("#", 1)[0].split()
                if len(fields) >= 2:
                    budget[fields[0]] = int(fields[1])
        if "default" not in budget:
            errors.append("%s: no `default` budget" % args.budgets)
        known = set(r[0] for r in rows if r[3])
        for name in sorted(budget):
            if name != "default" and name not in known:
                errors.append("%s: budget for unknown public function %s" % (args.budgets, name))
        print("\nbudget check (%s):" % os.path.basename(args.budgets))
        for name, _, total, pub, _ in rows:
            if not pub:
                continue
            lim = budget.get(name, budget.get("default", 0))
            if name in budget:
                print("  %-32s %5d / %5d %s" % (name, total, lim, "OK" if total <= lim else "OVER"))
            if total > lim:
                errors.append("%s needs %d bytes > budget %d" % (name, total, lim))
    for caller, callee in sorted(pruned):
        print("assumed never called: %s -> %s" % (caller, callee))
    if port_used:
        print("HAL port calls counted as 0 bytes (add the port implementation's own worst case): "
              + ", ".join(sorted(port_used)))
    if args.measured_run:
        p = subprocess.run(args.measured_run, capture_output=True, text=True)
        if p.returncode != 0:
            sys.stdout.write(p.stdout)
            errors.append("measured run failed with status %d" % p.returncode)
        meas = re.findall(r"^STACK (\S+) (\d+)$", p.stdout, re.M)
        if not meas:
            errors.append("measured run printed no STACK lines")
        print("\n%-*s %8s %8s" % (w, "measured call", "measured", "static"))
        for name, val in meas:
            if name not in g.frame:
                errors.append("%s: measured but unknown to the call graph (pass --ci-dir)" % name)
                continue
            total = worst(name)[0]
            flag = "" if int(val) <= total else "  <-- static bound too small"
            print("%-*s %8d %8d%s" % (w, name, int(val), total, flag))
            if int(val) > total:
                errors.append("%s: measured %s bytes > static %d" % (name, val, total))
    for e in sorted(set(errors)):
        print("ERROR: " + e, file=sys.stderr)
    return 1 if errors else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
