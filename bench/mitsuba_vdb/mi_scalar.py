"""mi_scalar.py: runs bench/mitsuba_side.py (imported unchanged) with Mitsuba's scalar_rgb variant.

  python3 mi_scalar.py SCENE.json GRID_PREFIX VARIANT OUT_DIR SPP:SEED [SPP:SEED ...]

Design: the arguments, the scene translation, the camera, the lights, the medium and the outputs
(OUT_DIR/mi_<spp>_<seed>.exr, OUT_DIR/timings.json) are all mitsuba_side.py's. Only its
sigma_t_grid is replaced: mitsuba_side builds the (nz, ny, nx, 3) sigma_t tensor with dr.arange
and dr.gather, which have no scalar overload, so in scalar variants the same tensor (density
times sigma_s + sigma_a per channel, channels last) is built here with numpy. bench/mitsuba_vdb.sh
uses scalar_rgb because llvm_ad_rgb aborts at the first render with Debian's libLLVM 14 and 15
("LLVM ERROR: Cannot select: ... fminimum"); bench/run expects libLLVM 19. A framed camera is
resolved by mitsuba_side through `spectrack info` from $SPECTRACK.
"""
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
import mitsuba as mi  # noqa: E402
import mitsuba_side as ms  # noqa: E402


def sigma_t_grid(path, dims, sigma_t):
    """The dense density dump times sigma_t per channel: a (nz, ny, nx, 3) tensor, channels last."""
    density = np.fromfile(path, dtype="<f4")
    n = dims[0] * dims[1] * dims[2]
    if density.size != n:
        raise SystemExit(f"mi_scalar: {path}: {density.size} values, the dims say {n}")
    grid = density.reshape(*dims, 1) * np.asarray(sigma_t, dtype=np.float32).reshape(1, 1, 1, 3)
    return mi.TensorXf(np.ascontiguousarray(grid, dtype=np.float32))


ms.sigma_t_grid = sigma_t_grid

if __name__ == "__main__":
    ms.main()
