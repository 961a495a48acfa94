#!/usr/bin/python3
"""Packs a build of spectrack for a GPU machine that has none of its Debian packages.

Design: the `device` tool's GPU machines (docs/benchmarks.md, GPU check) run a CUDA image with no package
registry reachable, so bench/gpu.sh cannot run scripts/setup.sh there. This packs what the built
programs need to run there into one .tar.xz: the programs (build/spectrack, spectrack_tests,
kernel_throughput, grid_export), pbrt-v4's grid as bench/pbrt_grid.py
generated it (when it has), every shared library they load (the whole closure, glibc and its loader
included, so the bundle does not depend on the target's libraries) and the generated volumes of
data/volumes. The programs' interpreter and RPATH are rewritten (patchelf) to PREFIX/lib, where
bench/gpu.sh unpacks the bundle. OpenCL is reached through the bundled ocl-icd loader, which reads
the vendor's ICD file (/etc/OpenCL/vendors, written by gpu.sh for NVIDIA's driver library).

Libraries the programs never call on such a machine but OpenImageIO links for formats we do not
read or write (OpenCV, FFmpeg, DCMTK, libheif, LibRaw) and Open MPI (only `spectrack mpi` calls
it) are replaced by generated stubs: shared objects with the same SONAME and symbol versions
that define every symbol a bundled object imports from them, each function returning 0 (static
initialisers of OpenImageIO's plugins call some at load; ST_GPU_STUB_TRACE=1 logs every call).
That keeps the bundle near 40 MB instead of 370 MB (their closures: GDAL, codecs, ICU, ...).
This is packaging for benchmarks only; the product itself is built and installed from Debian.

Usage (from the repository root, after a build; needs patchelf, gcc and xz):
  /usr/bin/python3 bench/gpu_bundle.py [--out .gpu/bundle.tar.xz] [--prefix /opt/spectrack-gpu]
      [--shared]   also pack ../shared/data/vdb (the tests that read it then run there too)
      [--old BIN]  also pack another spectrack binary as spectrack_old (same libraries): gpu.sh's
                   grid step then renders with both, interleaved, for before/after ratios
"""
import argparse
import os
import re
import shutil
import subprocess
import sys
import tarfile
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PROGRAMS = ["spectrack", "spectrack_tests", "kernel_throughput", "grid_export"]
# SONAME patterns replaced by stubs (see the design note)
STUB = re.compile(r"^lib(opencv_|av(codec|format|util|device|filter)|sw(scale|resample)|dcm|oflog|ofstd|heif|"
                  r"mpi|open-(pal|rte)|hwloc|pmix|event)")


def sh(*cmd):
    return subprocess.run(cmd, check=True, capture_output=True, text=True).stdout


def ldconfig_map():
    m = {}
    for line in sh("/sbin/ldconfig", "-p").splitlines():
        g = re.match(r"\s*(\S+) \((libc6,x86-64[^)]*)\) => (\S+)", line)
        if g and g.group(1) not in m:
            m[g.group(1)] = g.group(3)
    return m


def needed(path):
    return re.findall(r"\(NEEDED\)\s+Shared library: \[([^\]]+)\]", sh("readelf", "-dW", path))


def dynsyms(path):
    """(name, version, type, size, defined) of each dynamic symbol (readelf --dyn-syms -W)."""
    out = []
    for line in sh("readelf", "--dyn-syms", "-W", path).splitlines():
        f = line.split()
        if len(f) < 8 or not f[0].rstrip(":").isdigit():
            continue
        size = int(f[2], 16) if f[2].startswith("0x") else int(f[2])
        name = f[7]
        ver = ""
        if "@" in name:
            name, _, ver = name.partition("@")
            ver = ver.lstrip("@")
        ver = re.sub(r"\s*\(\d+\)$", "", ver)
        out.append((name, ver, f[3], size, f[6] != "UND"))
    return out


def make_stub(soname, lib_path, imports, work):
    """A shared object named soname defining every symbol of lib_path that `imports` holds."""
    defined = {}
    for name, ver, typ, size, is_def in dynsyms(lib_path):
        if is_def and name in imports and typ in ("FUNC", "OBJECT", "IFUNC", "TLS", "NOTYPE"):
            defined.setdefault(name, (ver, typ, size))
    c = ["#include <stdlib.h>", "#include <stdio.h>",
         f'static long st_stub(const char* s) {{ if (getenv("ST_GPU_STUB_TRACE")) fprintf(stderr, "gpu bundle: stub {soname}: %s called\\n", s); return 0; }}']
    versions = {}
    for i, (name, (ver, typ, size)) in enumerate(sorted(defined.items())):
        if typ == "OBJECT" or typ == "TLS":
            tls = "__thread " if typ == "TLS" else ""
            c.append(f'{tls}char st_o{i}[{max(size, 1)}] __asm__("{name}") __attribute__((aligned(64)));')
        else:
            c.append(f'long st_f{i}(void) __asm__("{name}");')
            c.append(f'long st_f{i}(void) {{ return st_stub("{name}"); }}')
        versions.setdefault(ver, []).append(name)
    src = os.path.join(work, soname + ".c")
    with open(src, "w") as f:
        f.write("\n".join(c) + "\n")
    cmd = ["gcc", "-shared", "-fPIC", "-O0", "-o", os.path.join(work, soname), src, f"-Wl,-soname,{soname}"]
    named = [v for v in versions if v]
    if named:
        vs = os.path.join(work, soname + ".map")
        with open(vs, "w") as f:
            for v in named:
                f.write(f"{v} {{ global: {'; '.join(versions[v])}; }};\n")
            if "" in versions:  # unversioned imports bind to the first node
                f.write(f"ST_UNVERSIONED {{ global: {'; '.join(versions[''])}; }};\n")
        cmd.append(f"-Wl,--version-script={vs}")
    subprocess.run(cmd, check=True)
    return os.path.join(work, soname), len(defined)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default=os.path.join(ROOT, ".gpu", "bundle.tar.xz"))
    ap.add_argument("--prefix", default="/opt/spectrack-gpu")
    ap.add_argument("--shared", action="store_true")
    ap.add_argument("--old")
    a = ap.parse_args()
    for tool in ("patchelf", "gcc", "readelf"):
        if not shutil.which(tool):
            sys.exit(f"gpu_bundle.py: {tool} is needed (apt-get install patchelf gcc binutils)")
    progs = [os.path.join(ROOT, "build", p) for p in PROGRAMS] + ([os.path.abspath(a.old)] if a.old else [])
    for p in progs:
        if not os.path.exists(p):
            sys.exit(f"gpu_bundle.py: {p} is missing: build first (scripts/setup.sh)")
    sonames = ldconfig_map()
    # the closure, stopping at stubbed libraries
    keep, stub, todo = {}, {}, list(progs)
    seen = set()
    while todo:
        obj = todo.pop()
        for n in needed(obj):
            if n in seen:
                continue
            seen.add(n)
            path = sonames.get(n)
            if path is None:
                sys.exit(f"gpu_bundle.py: {n} (needed by {obj}) is not in ldconfig's cache")
            if STUB.match(n):
                stub[n] = path
            else:
                keep[n] = path
                todo.append(os.path.realpath(path))
    # what the stubs must define: every undefined symbol of a bundled object, and every dynamic
    # symbol of the programs (objects they copy-relocate appear defined in them)
    imports = set()
    for obj in progs + [os.path.realpath(p) for p in keep.values()]:
        imports.update(name for name, ver, typ, size, is_def in dynsyms(obj) if not is_def or obj in progs)
    loader = os.path.realpath("/lib64/ld-linux-x86-64.so.2")
    with tempfile.TemporaryDirectory() as work:
        lib = os.path.join(work, "lib")
        binp = os.path.join(work, "bin")
        os.makedirs(lib)
        os.makedirs(binp)
        for n, p in keep.items():
            shutil.copy2(os.path.realpath(p), os.path.join(lib, n))
        shutil.copy2(loader, os.path.join(lib, "ld-linux-x86-64.so.2"))
        # ocl-icd is dlopen'ed by nobody: libOpenCL.so.1 is NEEDED, so it is in keep already
        n_syms = 0
        for n, p in stub.items():
            s, k = make_stub(n, os.path.realpath(p), imports, work)
            shutil.copy2(s, os.path.join(lib, n))
            n_syms += k
        for p in progs:
            dst = os.path.join(binp, "spectrack_old" if a.old and p == os.path.abspath(a.old) else os.path.basename(p))
            shutil.copy2(p, dst)
            subprocess.run(["strip", "--strip-debug", dst], check=True)
            subprocess.run(["patchelf", "--set-interpreter", f"{a.prefix}/lib/ld-linux-x86-64.so.2",
                            "--force-rpath", "--set-rpath", f"{a.prefix}/lib", dst], check=True)
        # the source folder the programs were built in (their baked-in paths): gpu.sh links it
        with open(os.path.join(work, "source_dir"), "w") as f:
            f.write(ROOT + "\n")
        os.makedirs(os.path.dirname(os.path.abspath(a.out)), exist_ok=True)
        with tarfile.open(a.out, "w:xz", preset=6) as t:
            t.add(binp, "bin")
            t.add(os.path.join(work, "source_dir"), "source_dir")
            t.add(lib, "lib")
            t.add(os.path.join(ROOT, "data", "volumes"), "volumes")
            grid = os.path.join(os.environ.get("SPECTRACK_BENCH_CACHE", os.path.expanduser("~/.cache/spectrack/bench")), "pbrt-grid")
            if os.path.exists(os.path.join(grid, "st_chromatic_g0.6.json")):  # bench/pbrt_grid.py's scene
                for f in ("st_chromatic_g0.6.json", "chromatic_grid.vdb"):
                    t.add(os.path.join(grid, f), "grid/" + f)
            if a.shared:
                t.add(os.path.join(os.path.dirname(ROOT), "shared", "data", "vdb"), "shared_vdb")
    print(f"gpu_bundle.py: {a.out}: {os.path.getsize(a.out) / 2**20:.1f} MiB; {len(keep)} libraries, "
          f"{len(stub)} stubs ({n_syms} symbols): {' '.join(sorted(stub))}")


if __name__ == "__main__":
    main()
