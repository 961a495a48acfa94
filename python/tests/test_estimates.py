"""Statistical checks through the Python module, each with a twin that injects a 3% error and must
fail: a white furnace built with load_dict renders 1, and a constant numpy volume renders the
homogeneous box of the same coefficients (4 standard errors, fixed seeds)."""
import numpy as np

import spectrack
from conftest import mean_and_se, within_4se


def furnace(tracker):
    return {
        "format": "spectrack-scene/1",
        "camera": {"type": "perspective", "position": [0.2, 0.1, -3], "look_at": [0, 0, 0], "up": [0, 1, 0],
                   "fov_deg": 30},
        "film": {"width": 24, "height": 24, "spp": 128},
        "render": {"tracker": tracker, "seed": 11},
        "lights": [{"type": "environment", "radiance": [1, 1, 1]}],
        "media": [{"type": "homogeneous", "bounds": [[-0.6, -0.5, -0.4], [0.5, 0.6, 0.7]],
                   "sigma_s": [1.0, 3.0, 9.0], "sigma_a": [0, 0, 0], "phase": {"type": "hg", "g": 0.4}}],
    }


def test_white_furnace_renders_one():
    for tracker in ("spectral-decomposition", "delta-per-channel"):
        rgb = spectrack.load_dict(furnace(tracker)).render().rgb
        for c in range(3):
            ok, m, se = within_4se(rgb[..., c], 1.0)
            assert ok, f"{tracker} channel {c}: {m} +- {se}"
            assert 0 < se < 0.005, f"{tracker}: the standard error {se} cannot see a 3% error"
            twin_ok, _, _ = within_4se(rgb[..., c] * 1.03, 1.0)
            assert not twin_ok, f"{tracker} channel {c}: the 3% twin passes"


N, NZ, H = 48, 16, 1.0 / 16  # voxels across x and y, along z; the voxel size


def slab_scene(medium, seed):
    return {
        "format": "spectrack-scene/1",
        "camera": {"type": "orthographic", "position": [1.47, 1.47, -3], "look_at": [1.47, 1.47, 0], "up": [0, 1, 0],
                   "height": 1.0},
        "film": {"width": 24, "height": 24, "spp": 96},
        "render": {"seed": seed},
        "lights": [{"type": "environment", "radiance": [1, 1, 1]}],
        "media": [{**medium, "sigma_s": [1.5, 1.0, 0.5], "sigma_a": [0.3, 0.3, 0.3]}],
    }


def test_constant_numpy_volume_equals_the_homogeneous_box():
    density = np.ones((N, N, NZ), dtype=np.float32)
    vol = spectrack.Volume.from_numpy(density, voxel_size=H, origin=(0, 0, 0))
    # voxel centres at i * H; trilinear support ends one voxel out, so the box of the same optical
    # depth along an axis spans half a voxel beyond the outer centres
    lo, hi = -0.5 * H, [(N - 0.5) * H, (N - 0.5) * H, (NZ - 0.5) * H]
    box = {"type": "homogeneous", "bounds": [[lo, lo, lo], hi]}
    a = spectrack.load_dict(slab_scene({"type": "vdb", "file": vol}, seed=3)).render().rgb
    b = spectrack.load_dict(slab_scene(box, seed=4)).render().rgb
    assert 0.05 < b.mean() < 0.95
    for c in range(3):
        diff = a[..., c].astype(np.float64) - b[..., c]
        m, se = mean_and_se(diff)
        assert abs(m) <= 4 * se, f"channel {c}: volume - box = {m} +- {se}"
        twin = a[..., c].astype(np.float64) - 1.03 * b[..., c]
        tm, tse = mean_and_se(twin)
        assert abs(tm) > 4 * tse, f"channel {c}: the 3% twin passes ({tm} +- {tse})"
