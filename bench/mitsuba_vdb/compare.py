"""compare.py: the statistics and the verdict of bench/mitsuba_vdb.sh for one scene.

  python3 compare.py NAME ST_1.exr ST_2.exr MI_1.exr MI_2.exr MASK.exr [--z-max 4] [--block-max 2]

Design: each renderer renders the scene twice (two seeds), and the image compared is the mean of
the two. The per-pixel variance of that mean is (a - b)^2 / 4, which has one degree of freedom per
pixel but thousands over the image, so the standard error of a mean over N pixels is
sqrt(sum of those variances) / N ("pixel-pair SE"); every z uses it. The seed-to-seed SE
(|mean_1 - mean_2| / 2, one degree of freedom) is too coarse for a 4-SE test and is not used.
Per channel (linear RGB), three checks must hold:
- the image mean and the medium mean: z = (spectrack - mitsuba) / sqrt(SE_s^2 + SE_m^2), |z| <= z-max.
  The medium mean averages only the pixels with alpha > 0.05 in MASK.exr, an independent spectrack
  render (another seed, alpha on), so that the sky pixels, the same in both renderers, do not
  dilute a bias in the medium, and the selection does not correlate with the noise of the images
  compared;
- the 4x4 block ratio: the mean over 4x4-pixel blocks of (spectrack block mean - mitsuba block
  mean)^2 over the mean of the predicted variances of that difference. Noise alone gives 1 (the
  spread is about sqrt(2 / blocks), 0.1 for the 150 to 192 blocks here); structure that cancels
  in the means (a shift, a blur, a misplaced or mis-rotated medium) raises it. It must stay below
  block-max;
- the shift fit: a least-squares fit of the difference image on [I, dI/dx, dI/dy] over the inner
  pixels gives a relative scale and a sub-pixel shift (x right, y down) of spectrack's image
  against Mitsuba's, with sandwich SEs from the per-pixel variances; |z| of each shift <= z-max.
  It is the most sensitive test of a grid-placement error: the half-voxel offset of the power
  check moves the image by about 0.17 px at 6 SE, while the means stay within 1 SE.
The spectrack EXRs are rendered with --no-alpha, so R, G, B hold the whole image. An EXR with
alpha on holds the sky seen directly in environment.R/G/B (docs/aov.md); it is added back when
present, so that such files compare correctly too. EXRs are read with Mitsuba's Bitmap
(scalar_rgb variant). It prints one line per channel, ending in "ok" or "FAIL (reasons)", and
exits 1 when a check fails.
"""
import argparse
import sys

import mitsuba as mi
import numpy as np

mi.set_variant("scalar_rgb")


def channels(path):
    b = mi.Bitmap(path)
    arr = np.array(b, dtype=np.float64)
    if arr.ndim == 2:
        arr = arr[..., None]
    names = [b.struct_()[i].name for i in range(b.channel_count())]
    return arr, names


def load(path):
    """Linear RGB radiance (H, W, 3): R, G, B plus environment.R/G/B where present."""
    arr, names = channels(path)
    img = arr[..., [names.index(c) for c in "RGB"]]
    if "environment.R" in names:
        img = img + arr[..., [names.index("environment." + c) for c in "RGB"]]
    elif "A" in names:
        raise SystemExit(f"compare.py: {path} has alpha but no environment layer: render with --no-alpha")
    return img


def pair(a, b):
    """The mean image of two seeds and the per-pixel variance of that mean."""
    return 0.5 * (a + b), 0.25 * (a - b) ** 2


def mean_se(img, var, sel=None):
    if sel is not None:
        img, var = img[sel], var[sel]
    else:
        img, var = img.reshape(-1, 3), var.reshape(-1, 3)
    n = img.shape[0]
    return img.mean(axis=0), np.sqrt(var.sum(axis=0)) / n


def block_ratio(s, vs, m, vm, k=4):
    h, w = s.shape[0] // k * k, s.shape[1] // k * k

    def blocks(x):
        return x[:h, :w].reshape(h // k, k, w // k, k, 3)

    d = blocks(s).mean(axis=(1, 3)) - blocks(m).mean(axis=(1, 3))
    pred = (blocks(vs).sum(axis=(1, 3)) + blocks(vm).sum(axis=(1, 3))) / (k * k) ** 2
    return (d ** 2).mean(axis=(0, 1)) / pred.mean(axis=(0, 1)), d.shape[0] * d.shape[1]


def shift_fit(s, vs, m, vm):
    """Per channel: (scale, se), (shift_x, se), (shift_y, se) of spectrack against Mitsuba."""
    d = s - m
    v = vs + vm
    img = 0.5 * (s + m)
    gx = np.zeros_like(img)
    gy = np.zeros_like(img)
    gx[:, 1:-1] = 0.5 * (img[:, 2:] - img[:, :-2])
    gy[1:-1, :] = 0.5 * (img[2:, :] - img[:-2, :])
    inner = np.zeros(img.shape[:2], bool)
    inner[1:-1, 1:-1] = True
    out = []
    for c in range(3):
        sel = inner & (v[..., c] > 0)
        x = np.stack([img[..., c][sel], gx[..., c][sel], gy[..., c][sel]], 1)
        y = d[..., c][sel]
        vv = v[..., c][sel]
        xtx_inv = np.linalg.inv(x.T @ x)
        beta = xtx_inv @ (x.T @ y)
        cov = xtx_inv @ (x.T @ (x * vv[:, None])) @ xtx_inv  # sandwich with the per-pixel variance
        out.append(list(zip(beta, np.sqrt(np.diag(cov)))))
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("name")
    ap.add_argument("st1")
    ap.add_argument("st2")
    ap.add_argument("mi1")
    ap.add_argument("mi2")
    ap.add_argument("mask")
    ap.add_argument("--z-max", type=float, default=4.0)
    ap.add_argument("--block-max", type=float, default=2.0)
    ap.add_argument("--alpha-min", type=float, default=0.05)
    a = ap.parse_args()

    s, vs = pair(load(a.st1), load(a.st2))
    m, vm = pair(load(a.mi1), load(a.mi2))
    if s.shape != m.shape:
        raise SystemExit(f"compare.py: {a.name}: spectrack {s.shape} vs mitsuba {m.shape}")
    marr, mnames = channels(a.mask)
    if "A" not in mnames:
        raise SystemExit(f"compare.py: {a.mask} has no alpha channel")
    sel = marr[..., mnames.index("A")] > a.alpha_min
    if sel.sum() == 0:
        raise SystemExit(f"compare.py: {a.name}: the medium mask is empty")

    im_s, im_se_s = mean_se(s, vs)
    im_m, im_se_m = mean_se(m, vm)
    md_s, md_se_s = mean_se(s, vs, sel)
    md_m, md_se_m = mean_se(m, vm, sel)
    z_im = (im_s - im_m) / np.sqrt(im_se_s ** 2 + im_se_m ** 2)
    z_md = (md_s - md_m) / np.sqrt(md_se_s ** 2 + md_se_m ** 2)
    ratio, nblocks = block_ratio(s, vs, m, vm)
    fit = shift_fit(s, vs, m, vm)

    failed = False
    for c, ch in enumerate("RGB"):
        (_, _), (sx, sx_se), (sy, sy_se) = fit[c]
        zx, zy = sx / sx_se, sy / sy_se
        why = []
        if abs(z_im[c]) > a.z_max:
            why.append("image z")
        if abs(z_md[c]) > a.z_max:
            why.append("medium z")
        if not ratio[c] < a.block_max:
            why.append("block ratio")
        if abs(zx) > a.z_max or abs(zy) > a.z_max:
            why.append("shift")
        failed |= bool(why)
        print(f"{a.name:18s} {ch}  image st {im_s[c]:.5f} ({im_se_s[c]:.5f}) mi {im_m[c]:.5f} ({im_se_m[c]:.5f}) z {z_im[c]:+5.2f}"
              f" | medium {sel.sum()} px st {md_s[c]:.5f} ({md_se_s[c]:.5f}) mi {md_m[c]:.5f} ({md_se_m[c]:.5f}) z {z_md[c]:+5.2f}"
              f" | block ratio {ratio[c]:.2f} ({nblocks})"
              f" | shift x {sx:+.3f} px z {zx:+5.2f} y {sy:+.3f} px z {zy:+5.2f}"
              f" | {'FAIL (' + ', '.join(why) + ')' if why else 'ok'}", flush=True)
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
