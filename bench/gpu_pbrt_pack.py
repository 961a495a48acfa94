#!/usr/bin/python3
"""Packs a pbrt-v4 GPU build for the device machine, in parts that one device run each can carry.

Design: the second GPU peer of issue 39 is pbrt-v4's own GPU renderer (CUDA + OptiX) on the grid
both renderers share (../shared/bench/pbrt-grid). The repository holds no pbrt code, binary or
build recipe; a pbrt-v4 that the user built with CUDA and OptiX (for the device's GPU
architecture) is packed with the libraries it loads that a bare Ubuntu machine may
lack (OpenEXR, Imath, the GL dispatch and X11 client libraries: everything `ldd` lists except
the C and C++ runtimes and the NVIDIA driver's own), and pbrt's grid scenes with the independent
sampler (bench/pbrt_grid.py's pbrt_scene). The stripped sm_90 binary is about 100 MB, 74 MB
compressed, more than one run's 64 MiB carry, so the .tar.xz is cut into parts of at most
--part-mib: carried to the same warm machine over successive runs (a carried path that the next
run does not name stays there), `bench/gpu.sh` step 10 joins them in name order and unpacks the
result to /opt/pbrt-gpu: bin/pbrt, lib/, grid/.

Usage (after bench/pbrt_grid.py has made the grid once, or with --grid DIR):
  /usr/bin/python3 bench/gpu_pbrt_pack.py PBRT_BINARY [--out .gpu/pbrt.tar.xz] [--part-mib 60]
Prints every part and its size.
"""
import argparse
import glob
import io
import lzma
import os
import re
import subprocess
import sys
import tarfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import pbrt_grid  # noqa: E402 (the grid's cache and pbrt's scene with the independent sampler)

# Libraries the device provides itself: the C and C++ runtimes (newer there) and NVIDIA's driver.
SYSTEM = re.compile(r"^(ld-linux|libc\.|libm\.|libdl\.|librt\.|libpthread\.|libgcc_s\.|libstdc\+\+\.|"
                    r"libcuda\.|libnvoptix\.|libnvidia-)")


def libraries(binary):
    """(soname, path) of what the binary loads, less the system's; an unresolved one is an error
    unless the device's driver provides it"""
    out = subprocess.run(["ldd", binary], capture_output=True, text=True, check=True).stdout
    libs = []
    for line in out.splitlines():
        m = re.match(r"\s*(\S+)\s+=>\s+(\S+)", line)
        if not m or SYSTEM.match(m.group(1)):
            continue
        if m.group(2) == "not":
            sys.exit(f"gpu_pbrt_pack.py: {binary} needs {m.group(1)}, which ldd does not find here")
        libs.append((m.group(1), os.path.realpath(m.group(2))))
    return libs


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("pbrt", help="a pbrt-v4 binary built with CUDA (pbrt --gpu)")
    ap.add_argument("--out", default=".gpu/pbrt.tar.xz")
    ap.add_argument("--part-mib", type=float, default=60.0, help="largest part (one run carries 64 MiB)")
    ap.add_argument("--grid", help="the grid's folder (default: bench/pbrt_grid.py's cache)")
    a = ap.parse_args()
    if not os.access(a.pbrt, os.X_OK):
        sys.exit(f"gpu_pbrt_pack.py: {a.pbrt}: not an executable")
    grid = a.grid or pbrt_grid.prepare_grid()
    buf = io.BytesIO()
    with tarfile.open(fileobj=buf, mode="w") as t:
        t.add(a.pbrt, "bin/pbrt")
        for soname, path in libraries(a.pbrt):
            t.add(path, "lib/" + soname)
        for g in ("0.0", "0.6"):
            t.add(pbrt_grid.pbrt_scene(grid, f"chromatic_grid_g{g}.pbrt"), f"grid/chromatic_grid_g{g}_independent.pbrt")
    data = lzma.compress(buf.getvalue(), preset=9 | lzma.PRESET_EXTREME)
    for old in glob.glob(a.out + "*"):
        os.remove(old)
    os.makedirs(os.path.dirname(os.path.abspath(a.out)), exist_ok=True)
    part = int(a.part_mib * 2**20)
    if len(data) <= part:
        with open(a.out, "wb") as f:
            f.write(data)
        print(f"{a.out}: {len(data) / 2**20:.1f} MiB")
        return
    for k in range(0, len(data), part):
        name = f"{a.out}.part{k // part}"
        with open(name, "wb") as f:
            f.write(data[k:k + part])
        print(f"{name}: {min(part, len(data) - k) / 2**20:.1f} MiB")


if __name__ == "__main__":
    main()
