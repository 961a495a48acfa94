#!/usr/bin/python3
"""Packs Mitsuba 3's CUDA variant for the device machine, which has Python 3.12 and no registry.

Design: the peer on the same GPU is Mitsuba 3's `cuda_ad_rgb` variant (it needs only the NVIDIA
driver). The cp312 wheels of mitsuba and drjit are about 67 MB, more than one device run carries
(64 MiB) beside spectrack's bundle, and most of that is what the check never loads: one Python
module per variant (cuda_ad_*, llvm_ad_*, scalar_*, each about 1.3 MB compressed), about 90
plugins (each holds every variant), headers, type stubs and the sun-sky tables. This keeps the
shared libraries, the Python packages, the modules of the variants asked for (--keep; the CUDA
variant imports without scalar_rgb) and the plugins the bench scenes load (--plugins, PLUGINS
below), and writes one .tar.xz whose top level is the `mitsuba` and `drjit` packages: unpacked
into a folder on PYTHONPATH, `import mitsuba` works. About 20 MiB, so it travels in the same run
as the bundle.

Usage (the wheels from pip on a machine with the registry, e.g.
  pip download --no-deps --only-binary=:all: --python-version 3.12 \
      --platform manylinux_2_28_x86_64 mitsuba==3.9.1 drjit==1.5.0 -d WHEELS):
  /usr/bin/python3 bench/gpu_mitsuba_pack.py WHEELS [--out .gpu/mitsuba.tar.xz] [--keep cuda_ad_rgb]
Prints the size. A check of the pack without a GPU: `--keep cuda_ad_rgb,llvm_ad_rgb`, then
bench/gpu_peer.py with `--variant llvm_ad_rgb` under a Python 3.12 (docs/benchmarks.md).
"""
import argparse
import glob
import io
import os
import re
import tarfile
import zipfile

VARIANT = re.compile(r"^mitsuba/((?:scalar|llvm|cuda)_[a-z_]+)\.cpython-\d+[^/]*\.so$")
PLUGIN = re.compile(r"^mitsuba/plugins/([a-z_0-9]+)\.so$")
# The plugins bench/mitsuba_side.py's scenes load (volpath and volpathmis, sun and sky, HG and
# isotropic media), as `strace -e openat` lists them for every bench scene it renders.
PLUGINS = ("box constant constvolume cube directional gridvolume hdrfilm heterogeneous hg independent "
           "isotropic merge null perspective srgb volpath volpathmis")
# Headers, build files, stubs and the sun-sky tables: nothing a render of those scenes opens.
DROP = ("mitsuba/include/", "drjit/include/", "mitsuba/cmake/", "drjit/cmake/", "mitsuba/pkgconfig/",
        "mitsuba/data/sunsky/")


def keep(name, variants, plugins):
    m = VARIANT.match(name)
    if m:
        return m.group(1) in variants
    m = PLUGIN.match(name)
    if m:
        return plugins is None or m.group(1) in plugins
    return not name.endswith(".pyi") and ".dist-info/" not in name and not name.startswith(DROP)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("wheels", help="folder holding the mitsuba and drjit cp312 wheels")
    ap.add_argument("--out", default=".gpu/mitsuba.tar.xz")
    ap.add_argument("--keep", default="cuda_ad_rgb")
    ap.add_argument("--plugins", default=PLUGINS, help="plugins to keep (names, space-separated), or 'all'")
    a = ap.parse_args()
    variants = set(a.keep.split(","))
    plugins = None if a.plugins == "all" else set(a.plugins.split())
    wheels = sorted(glob.glob(os.path.join(a.wheels, "mitsuba-*-cp312-*.whl")) +
                    glob.glob(os.path.join(a.wheels, "drjit-*-cp312-*.whl")))
    if len(wheels) != 2:
        raise SystemExit(f"gpu_mitsuba_pack: need one cp312 wheel each of mitsuba and drjit in {a.wheels}, found {wheels}")
    os.makedirs(os.path.dirname(os.path.abspath(a.out)), exist_ok=True)
    kept = dropped = 0
    with tarfile.open(a.out, "w:xz", preset=6) as tar:
        for w in wheels:
            with zipfile.ZipFile(w) as z:
                for i in z.infolist():
                    if i.is_dir() or not keep(i.filename, variants, plugins):
                        dropped += i.file_size
                        continue
                    data = z.read(i)
                    t = tarfile.TarInfo(i.filename)
                    t.size = len(data)
                    t.mode = 0o755 if i.filename.endswith(".so") else 0o644
                    tar.addfile(t, io.BytesIO(data))
                    kept += i.file_size
    print(f"gpu_mitsuba_pack: {a.out}: {os.path.getsize(a.out) / 2**20:.1f} MiB "
          f"({kept / 2**20:.0f} MiB unpacked kept, {dropped / 2**20:.0f} MiB dropped; variants {sorted(variants)})")


if __name__ == "__main__":
    main()
