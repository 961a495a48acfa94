#!/usr/bin/env python3
"""bench/adaptive_oracle.py REF.exr NAME=PIXELS.txt[,NAME=PIXELS.txt] TARGET A B FIXED [LABEL]: how fast adaptive sampling
could be under the noise target's statistic (docs/adaptive.md "Measured"), from a long uniform render.

REF.exr is a long uniform render with the variance layer: per pixel its mean m_p and the variance
of one sample, sigma_p^2 = (variance layer) x spp, give rho_p = mean_c sigma_c^2 / max(m_p, floor)^2
with noise.h's floor (kNoiseFloor x the mean brightness of the counted pixels), and the samples
n_p = rho_p / TARGET^2 that bring the pixel's relative error to TARGET. Each PIXELS.txt is the
SPECTRACK_ADAPTIVE_PIXELS trace of an adaptive render of the same film: per pixel its samples and
work (density lookups and majorant steps); the first one's ratio w_p is the pixel's work per sample. A sample
of pixel p costs c_p = A + B w_p CPU seconds (A: the per-sample cost, B: the cost of one unit of
work; bench/adaptive_oracle.sh fits them), and a render costs FIXED seconds on top (process start,
scene and kernel-cache load). Prints the cost of

  uniform: every pixel takes the 95th-percentile pixel's n_p (nearest rank over the counted pixels,
           at least 16): the uniform render that just meets the target;
  ideal:   every pixel takes max(16, n_p), except the 5% allowance of counted pixels (those the
           percentile lets end above the target), which take 16 (the pilot): excused by the
           largest n_p, or by the largest cost c_p n_p; or, no pixel noisier than in the uniform
           render, excused pixels take the uniform render's samples (or n_p where fewer);
  rule's cap: every pixel takes what brings it to the aim (0.9 TARGET, kAdaptiveAim, or TARGET
           itself), at most the cap of adaptive_cap: the 97.5th-percentile pixel's samples (half the
           allowance, kAdaptiveCapShare), at most twice the 95th's: the present rule without rounds,
           weights or neighbourhood;
  measured: each adaptive render of PIXELS.txt, its samples times c_p;

and the ratios uniform / each, for the samples alone (sum n_p) and in CPU seconds with FIXED.
No rounds, no drift, no noise in rho: a bound for any rule that decides from samples."""
import math
import sys

import numpy as np
import OpenImageIO as oiio

NOISE_FLOOR, PERCENTILE, PILOT = 0.05, 0.95, 16


def load_ref(path):
    b = oiio.ImageBuf(path)
    spec = b.spec()
    px = b.get_pixels(oiio.FLOAT).reshape(spec.height * spec.width, spec.nchannels).astype(np.float64)
    ch = {c: px[:, i] for i, c in enumerate(spec.channelnames)}
    spp = float(spec.getattribute("spectrack:spp") or spec.getattribute("spp") or 0)
    if spp <= 0:
        sys.exit(f"{path}: no spp in the metadata")
    if "A" in ch and "environment.R" in ch:  # a transparent film: the whole beauty adds the environment
        for c in "RGB":
            ch[c] = ch[c] + ch["environment." + c]
    m = (ch["R"] + ch["G"] + ch["B"]) / 3.0
    sigma2 = (ch["variance.R"] + ch["variance.G"] + ch["variance.B"]) / 3.0 * spp
    return m, sigma2, spp


def main():
    ref, pixels, target, a, b, fixed = sys.argv[1:7]
    label = sys.argv[7] if len(sys.argv) > 7 else ref
    target, a, b, fixed = float(target), float(a), float(b), float(fixed)
    m, sigma2, spp = load_ref(ref)
    traces = []
    for item in pixels.split(","):  # NAME=FILE, the first one's work gives the costs
        name, path = item.split("=", 1)
        traces.append((name, np.loadtxt(path, comments="#")))
        if traces[-1][1].shape[0] != m.size:
            sys.exit(f"{path}: {traces[-1][1].shape[0]} pixels, {ref}: {m.size}")
    taken, work = traces[0][1][:, 1], traces[0][1][:, 2]
    w = np.where(taken > 0, work / np.maximum(taken, 1), 0.0)
    c = a + b * w  # CPU seconds per sample of each pixel
    counted = (m > 0) & (sigma2 > 0)
    floor = NOISE_FLOOR * m[counted].mean()
    rho = np.where(counted, sigma2 / np.maximum(m, floor) ** 2, 0.0)
    need = np.where(counted, np.ceil(rho / target**2), 0.0)
    count = int(counted.sum())
    allowance = count - math.ceil(PERCENTILE * count)  # pixels that may end above the target
    rank = math.ceil(PERCENTILE * count) - 1
    n_uniform = max(PILOT, np.sort(need[counted])[rank])

    def ideal(aim, excused_share, by_cost, excused_spp=PILOT):
        n = np.maximum(PILOT, np.ceil(need / aim**2))
        k = int(math.floor(allowance * excused_share))
        if k > 0:
            excused_n = np.minimum(n, excused_spp)
            key = np.where(counted, (c if by_cost else 1.0) * (n - excused_n), -np.inf)
            top = np.argsort(-key)[:k]
            n[top] = excused_n[top]
        return n

    rows = [("uniform", np.full(m.size, float(n_uniform)))]
    rows.append(("ideal, 5% excused by samples", ideal(1.0, 1.0, False)))
    rows.append(("ideal, 5% excused by cost", ideal(1.0, 1.0, True)))
    rows.append(("ideal, 5% by cost, excused take uniform's", ideal(1.0, 1.0, True, n_uniform)))

    def capped(aim):  # the rule's cap: the 97.5th-percentile need at the aim (at most twice the 95th's)
        n = np.maximum(PILOT, np.ceil(need / aim**2))
        ranked = np.sort(n[counted])
        cap = min(ranked[math.ceil(0.975 * count) - 1], 2 * ranked[rank])
        return np.minimum(n, max(cap, 2 * PILOT))

    rows.append(("rule's cap (2.5% capped at the 97.5th), aim 0.9", capped(0.9)))
    rows.append(("rule's cap (2.5% capped at the 97.5th), aim 1", capped(1.0)))
    for name, t in traces:
        rows.append((f"measured: {name}", t[:, 1]))
    print(f"{label}: {m.size} pixels, {count} counted, allowance {allowance}, reference {spp:.0f} spp,"
          f" target {target}, per-sample cost {a * 1e6:.2f} us + {b * 1e9:.1f} ns per work unit, fixed {fixed:.2f} s;"
          f" work per sample: median {np.median(w):.1f}, counted mean {w[counted].mean():.1f}, max {w.max():.0f}")
    u_samples, u_cost = rows[0][1].sum(), (rows[0][1] * c).sum()
    for name, n in rows:
        s, cost = n.sum(), (n * c).sum()
        print(f"  {name:46s} mean spp {s / m.size:8.1f}  cpu {cost + fixed:7.2f} s  uniform/this: samples"
              f" {u_samples / s:5.2f}x, cpu {(u_cost + fixed) / (cost + fixed):5.2f}x (without fixed {u_cost / cost:5.2f}x)")


if __name__ == "__main__":
    main()
