"""error_vs_time.py: the issue-4 benchmark (bench/run calls it): error against time, costs per
tracker, kernel throughput and Mitsuba 3 side by side, in one run, written to bench/results/ and
to the issue-4 section of bench/RESULTS.md.

Design:
- Reference per scene: two independent halves (seeds 1000 and 1001, REF_SPP/2 spp each) rendered by
  the reference tracker, cached outside git under the cache folder, keyed by a SHA-1 of the scene
  text, the kernels and sources, the binary and the settings. The reference is their mean; its own
  noise, var_ref = mean((A - B)^2) / 4 per pixel (the variance of the mean of two independent
  halves), is subtracted from every measured MSE, so MSE = mean((I - ref)^2) - var_ref is unbiased
  for the test image's own error. The test renders use seeds 1, 2, ..., never the reference seeds.
- Ladder: doubling spp. The loop is seed, then spp, then tracker innermost, so the trackers of a
  scene run interleaved in time and share whatever load the machine has.
- Efficiency of a tracker = 1 / (MSE x seconds_render) at the top of the ladder, MSE and seconds
  averaged over the seeds; reported relative to delta-per-channel measured in the same run.
- Costs per camera sample from the stats JSON of the top-spp render of the first seed.
- Mitsuba 3 (optional): bench/mitsuba_side.py in the venv's Python renders the same ladder and a
  high-spp pair of halves; both renderers are scored against the same (spectrack) reference, and
  Mitsuba's high-spp mean is compared with our reference against the noise of both.
"""
import argparse
import hashlib
import json
import math
import os
import platform
import shutil
import subprocess
import sys
import time

import numpy as np
import OpenImageIO as oiio

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BIN = os.path.join(ROOT, "build", "spectrack")
SECTION = "## Error against time, costs, throughput and Mitsuba 3 (issue 4)"
SCHEMES = ["history-average", "history-max", "average", "max"]

# name, scene, configurations (tracker, scheme), ladder, quick ladder, reference spp (full, quick),
# reference tracker, Mitsuba side by side
SCENES = [
    dict(key="a", name="cloud_chromatic", title="(a) Disney cloud, chromatic, sun + sky",
         configs=[("delta-per-channel", None)] + [("spectral", s) for s in SCHEMES] +
                 [("decomposition", None), ("spectral-decomposition", "history-average"), ("spectral-mis", None)],
         ladder=[1, 2, 4, 8, 16, 32], quick=[1, 2, 4], ref=(1024, 32), ref_tracker=("spectral", "history-average"),
         mitsuba=True),
    dict(key="b", name="dense_subsurface", title="(b) dense, mildly heterogeneous, chromatic (subsurface-like)",
         configs=[("delta-per-channel", None), ("spectral", "history-average"), ("decomposition", None),
                  ("spectral-decomposition", "history-average"), ("spectral-mis", None)],
         ladder=[1, 2, 4, 8, 16], quick=[1, 2], ref=(256, 16), ref_tracker=("spectral-decomposition", "history-average"),
         mitsuba=True),
    dict(key="c", name="smoke_thin", title="(c) OpenVDB smoke, thin, achromatic",
         configs=[("delta-per-channel", None), ("delta", None), ("spectral", "history-average"),
                  ("decomposition", None), ("spectral-decomposition", "history-average"), ("spectral-mis", None)],
         ladder=[1, 2, 4, 8, 16, 32], quick=[1, 2, 4], ref=(1024, 32), ref_tracker=("delta", None), mitsuba=True),
    dict(key="d", name="emissive_heat", title="(d) emissive smoke (densityAndHeat, heat as emission)",
         configs=[("delta-per-channel", None), ("delta", None), ("spectral", "history-average"),
                  ("decomposition", None), ("spectral-decomposition", "history-average"), ("spectral-mis", None)],
         ladder=[1, 2, 4, 8, 16, 32], quick=[1, 2, 4], ref=(1024, 32), ref_tracker=("delta", None), mitsuba=False),
]


def label(tracker, scheme):
    return f"{tracker} ({scheme})" if tracker == "spectral" else tracker


def log(msg):
    print(f"[{time.strftime('%H:%M:%S')}] {msg}", flush=True)


def read_exr(path):
    # ImageInput, not ImageBuf: ImageBuf goes through OIIO's shared ImageCache, which can hand back
    # an earlier file of the same name.
    inp = oiio.ImageInput.open(path)
    if inp is None:
        raise RuntimeError(f"cannot read {path}: {oiio.geterror()}")
    px = inp.read_image(oiio.FLOAT)
    inp.close()
    if px is None:
        raise RuntimeError(f"cannot read {path}")
    return np.asarray(px, dtype=np.float64)[..., :3]


def render(scene_path, tracker, scheme, spp, seed, out_dir, tag, device):
    exr = os.path.join(out_dir, f"{tag}.exr")
    stats = os.path.join(out_dir, f"{tag}.json")
    cmd = [BIN, "render", scene_path, "--spp", str(spp), "--seed", str(seed), "--tracker", tracker,
           "-o", exr, "--stats-json", stats, "--quiet", "--no-alpha"]  # the whole image, no layers (docs/aov.md)
    if scheme:
        cmd += ["--scheme", scheme]
    if device:
        cmd += ["--device", device]
    subprocess.run(cmd, check=True)
    img = read_exr(exr)
    st = json.load(open(stats))
    os.remove(exr)
    return img, st


def file_digest(h, path):
    with open(path, "rb") as f:
        h.update(f.read())


def code_digest():
    """Hash of everything that changes an image: kernels, sources, the binary."""
    h = hashlib.sha1()
    for sub in ("kernels", "src"):
        for dp, _, fs in sorted(os.walk(os.path.join(ROOT, sub))):
            for f in sorted(fs):
                file_digest(h, os.path.join(dp, f))
    return h.hexdigest()[:12]


def quick_scene(src, dst, scale):
    """A copy of a scene with the film scaled by `scale` and file paths made absolute."""
    s = json.load(open(src))
    d = os.path.dirname(os.path.abspath(src))
    for m in s["media"]:
        if "file" in m:
            m["file"] = os.path.normpath(os.path.join(d, m["file"]))
    s["film"]["width"] = max(8, int(s["film"]["width"] * scale))
    s["film"]["height"] = max(8, int(s["film"]["height"] * scale))
    s["film"]["output"] = "/dev/null.exr"
    json.dump(s, open(dst, "w"), indent=1)
    return dst


def mse_against(img, ref, var_ref):
    return float(np.mean((img - ref) ** 2) - var_ref)


def reference(sc, scene_path, args, cache, codeh):
    spp = sc["ref"][1] if args.quick else sc["ref"][0]
    tr, sch = sc["ref_tracker"]
    h = hashlib.sha1()
    file_digest(h, scene_path)
    h.update(f"{codeh} {spp} {tr} {sch} {args.device} {args.quick}".encode())
    d = os.path.join(cache, f"ref-{sc['name']}-{h.hexdigest()[:12]}")
    os.makedirs(d, exist_ok=True)
    halves = []
    for seed in (1000, 1001):
        p = os.path.join(d, f"half_{seed}.npy")
        if not os.path.exists(p):
            log(f"{sc['name']}: reference half seed {seed}, {spp // 2} spp, {label(tr, sch)}")
            img, st = render(scene_path, tr, sch, spp // 2, seed, d, f"half_{seed}", args.device)
            np.save(p, img)
            json.dump(st, open(os.path.join(d, f"half_{seed}.stats.json"), "w"))
        halves.append(np.load(p))
    a, b = halves
    ref = 0.5 * (a + b)
    var_ref = float(np.mean((a - b) ** 2) / 4.0)
    secs = sum(json.load(open(os.path.join(d, f"half_{s}.stats.json")))["seconds_render"] for s in (1000, 1001))
    return ref, var_ref, dict(spp=spp, tracker=label(tr, sch), seconds=secs, dir=d, halves=(a, b))


def run_scene(sc, args, cache, codeh, work):
    scene_path = os.path.join(ROOT, "bench", "scenes", sc["name"] + ".json")
    if args.quick:
        scene_path = quick_scene(scene_path, os.path.join(work, sc["name"] + ".json"), 0.5)
    ref, var_ref, refinfo = reference(sc, scene_path, args, cache, codeh)
    ladder = sc["quick"] if args.quick else sc["ladder"]
    seeds = list(range(1, args.seeds + 1))
    rows = {label(*c): {} for c in sc["configs"]}
    stats_top = {}
    for seed in seeds:
        for spp in ladder:
            for tr, sch in sc["configs"]:
                tag = f"test_{tr}_{sch}_{spp}_{seed}"
                img, st = render(scene_path, tr, sch, spp, seed, work, tag, args.device)
                lab = label(tr, sch)
                rows[lab].setdefault(spp, []).append((mse_against(img, ref, var_ref), st["seconds_render"]))
                if spp == ladder[-1] and seed == seeds[0]:
                    stats_top[lab] = st
            log(f"{sc['name']}: seed {seed} {spp} spp done")
    res = dict(scene=sc, ref=refinfo, var_ref=var_ref, ladder=ladder, rows=rows, stats=stats_top,
               scene_path=scene_path, ref_mean=ref.mean(axis=(0, 1)).tolist())
    if sc["mitsuba"] and args.mitsuba_python:
        res["mitsuba"] = run_mitsuba(sc, scene_path, ref, var_ref, refinfo["halves"], ladder, seeds, args, cache, work)
    return res


def run_mitsuba(sc, scene_path, ref, var_ref, ref_halves, ladder, seeds, args, cache, work):
    scene = json.load(open(scene_path))
    med = scene["media"][0]
    vol = os.path.normpath(os.path.join(os.path.dirname(scene_path), med["file"]))
    prefix = os.path.join(work, sc["name"] + "_grid")
    subprocess.run([os.path.join(ROOT, "build", "grid_export"), vol, med.get("grid", "density"), prefix], check=True)
    out = os.path.join(work, "mitsuba_" + sc["name"])
    shutil.rmtree(out, ignore_errors=True)
    hi = (sc["ref"][1] if args.quick else sc["ref"][0]) // 2
    # Warm-up (JIT), then the ladder interleaved by seed, then two high-spp halves.
    jobs = [f"{ladder[0]}:999"] + [f"{spp}:{seed}" for seed in seeds for spp in ladder] + [f"{hi}:2000", f"{hi}:2001"]
    env = dict(os.environ)
    t0 = time.time()
    p = subprocess.run([args.mitsuba_python, os.path.join(ROOT, "bench", "mitsuba_side.py"), scene_path, prefix,
                        args.mitsuba_variant, out] + jobs, env=env, capture_output=True, text=True)
    if p.returncode != 0:
        log(f"mitsuba failed on {sc['name']} (skipped): {p.stderr[-2000:]}")
        return None
    timings = json.load(open(os.path.join(out, "timings.json")))
    rows = {}
    for seed in seeds:
        for spp in ladder:
            img = read_exr(os.path.join(out, f"mi_{spp}_{seed}.exr"))
            rows.setdefault(spp, []).append((mse_against(img, ref, var_ref), timings[f"{spp}:{seed}"]))
    a = read_exr(os.path.join(out, f"mi_{hi}_2000.exr"))
    b = read_exr(os.path.join(out, f"mi_{hi}_2001.exr"))
    mi_mean = 0.5 * (a + b)
    var_mi = float(np.mean((a - b) ** 2) / 4.0)
    diff = mi_mean - ref
    agree = dict(spp=2 * hi, mse=float(np.mean(diff ** 2)), expected=var_mi + var_ref,
                 mean_mi=mi_mean.mean(axis=(0, 1)).tolist(), mean_ref=ref.mean(axis=(0, 1)).tolist(),
                 seconds=timings[f"{hi}:2000"] + timings[f"{hi}:2001"])
    # Channel means: the difference against the standard error of both means (pixels are
    # independent; per-pixel variances of each mean from its halves).
    var_px = ((a - b) ** 2) / 4.0
    ra, rb = ref_halves
    var_px_ref = ((ra - rb) ** 2) / 4.0
    npx = a.shape[0] * a.shape[1]
    se = np.sqrt((var_px.sum(axis=(0, 1)) + var_px_ref.sum(axis=(0, 1)))) / npx
    agree["mean_z"] = (diff.mean(axis=(0, 1)) / np.maximum(se, 1e-30)).tolist()
    # 8x8-pixel blocks: noise averages down 64x, a systematic difference does not.
    def blocks(x):
        h, w = (x.shape[0] // 8) * 8, (x.shape[1] // 8) * 8
        return x[:h, :w].reshape(h // 8, 8, w // 8, 8, 3).mean(axis=(1, 3))
    bd = blocks(mi_mean) - blocks(ref)
    bexp = (blocks(var_px) + blocks(var_px_ref)) / 64.0
    agree["block_mse"] = float(np.mean(bd ** 2))
    agree["block_expected"] = float(np.mean(bexp))
    agree["max_mi"] = float(mi_mean.max())
    agree["rel_mean_diff"] = (diff.mean(axis=(0, 1)) / np.maximum(ref.mean(axis=(0, 1)), 1e-12)).tolist()
    agree["flip_h_mse"] = float(np.mean((mi_mean[:, ::-1] - ref) ** 2))
    np.save(os.path.join(out, "mi_high.npy"), mi_mean)
    furnace = run_furnace(sc, scene, scene_path, prefix, args, work)
    log(f"mitsuba {sc['name']}: done in {time.time() - t0:.0f} s")
    return dict(rows=rows, agree=agree, variant=args.mitsuba_variant, hi_dir=out, var_px_mean=float(var_px.mean()),
                mi_high=mi_mean, furnace=furnace)


def run_furnace(sc, scene, scene_path, prefix, args, work):
    """White furnace on the scene's own grid: sigma_a = 0 (sigma_s = the scene's sigma_t, so the
    extinction keeps its chroma), a uniform environment of radiance 1 and nothing else: every pixel
    is exactly 1. Ours (two trackers) and Mitsuba, 16 spp x 4 seeds each."""
    f = json.loads(json.dumps(scene))
    m = f["media"][0]
    m["sigma_s"] = [a + b for a, b in zip(m["sigma_s"], m["sigma_a"])]
    m["sigma_a"] = [0.0, 0.0, 0.0]
    f["lights"] = [{"type": "environment", "radiance": [1.0, 1.0, 1.0]}]
    m["file"] = os.path.normpath(os.path.join(os.path.dirname(scene_path), m["file"]))
    fpath = os.path.join(work, sc["name"] + "_furnace.json")
    json.dump(f, open(fpath, "w"))
    res = {}
    seeds = [1, 2, 3, 4]
    for tr, sch in [("delta-per-channel", None), ("spectral-decomposition", "history-average")]:
        imgs = [render(fpath, tr, sch, 16, s, work, f"furnace_{tr}_{s}", args.device)[0] for s in seeds]
        res[label(tr, sch)] = imgs
    out = os.path.join(work, "furnace_mitsuba_" + sc["name"])
    p = subprocess.run([args.mitsuba_python, os.path.join(ROOT, "bench", "mitsuba_side.py"), fpath, prefix,
                        args.mitsuba_variant, out] + [f"16:{s}" for s in seeds], capture_output=True, text=True)
    if p.returncode == 0:
        res[f"Mitsuba 3 ({args.mitsuba_variant})"] = [read_exr(os.path.join(out, f"mi_16_{s}.exr"))
                                                      for s in seeds]
    summary = {}
    for k, imgs in res.items():
        means = np.array([im.mean(axis=(0, 1)) for im in imgs])
        summary[k] = dict(mean=means.mean(axis=0).tolist(), seed_min=means.min(axis=0).tolist(),
                          seed_max=means.max(axis=0).tolist(), pixel_max=float(max(im.max() for im in imgs)),
                          pixel_min=float(min(im.min() for im in imgs)))
    return summary


def summarise(rows, ladder):
    """(mean MSE, mean seconds) per spp."""
    return {spp: (float(np.mean([m for m, _ in rows[spp]])), float(np.mean([t for _, t in rows[spp]]))) for spp in ladder}


def efficiency(summary, ladder):
    m, t = summary[ladder[-1]]
    return 1.0 / (m * t) if m > 0 else float("inf")


def plot(res, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    for lab, rows in res["rows"].items():
        s = summarise(rows, res["ladder"])
        xs = [s[k][1] for k in res["ladder"]]
        ys = [math.sqrt(max(s[k][0], 1e-30)) for k in res["ladder"]]
        ax.loglog(xs, ys, "o-", label=lab)
    if res.get("mitsuba"):
        s = summarise(res["mitsuba"]["rows"], res["ladder"])
        xs = [s[k][1] for k in res["ladder"]]
        ys = [math.sqrt(max(s[k][0], 1e-30)) for k in res["ladder"]]
        ax.loglog(xs, ys, "s--k", label=f"Mitsuba 3 volpath ({res['mitsuba']['variant']})")
    ax.set_xlabel("render seconds")
    ax.set_ylabel("RMSE against reference")
    ax.set_title(f"{res['scene']['title']}\nspp {res['ladder'][0]}..{res['ladder'][-1]}, reference {res['ref']['spp']} spp",
                 fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def save_png(img, path):
    x = np.clip(img, 0, None)
    x = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    x = (np.clip(x, 0, 1) * 255 + 0.5).astype(np.uint8)
    out = oiio.ImageBuf(oiio.ImageSpec(x.shape[1], x.shape[0], 3, oiio.UINT8))
    out.set_pixels(oiio.ROI(), x)
    out.write(path)


def fmt_e(x):
    return f"{x:.3g}"


def tables(results, tp, meta):
    L = [SECTION, ""]
    L += [f"Command: `bench/run{' --quick' if meta['quick'] else ''}` (one run; {meta['minutes']:.1f} min wall). "
          f"Machine: {meta['machine']}. Device: `{meta['device']}`. Date: {meta['date']}. Commit: {meta['commit']}"
          f"{' (plus uncommitted changes)' if meta['dirty'] else ''}. Load (`uptime`) at start: {meta['load_start']}; "
          f"at end: {meta['load_end']} (the CPUs may be shared with other builds; each scene's trackers run interleaved, "
          f"so ratios within a table share the same load).", ""]
    L += ["GPU: no GPU was lent to this task, so every figure is PoCL on the CPU. The benchmark takes `--device` "
          "(`bench/run --device P:D`) and runs unchanged on any OpenCL device.", ""]
    L += ["Method: RMSE over all pixels and channels against a reference made of two independent halves "
          "(seeds 1000/1001) whose own noise (mean squared half difference / 4) is subtracted from every MSE; "
          f"test renders use seeds 1..{meta['seeds']} and MSE and seconds are averaged over them. seconds = "
          "`seconds_render` (stage loop only, no VDB load or kernel build). Efficiency = 1 / (MSE x seconds) at the "
          "top of the ladder, relative to `delta-per-channel` in the same run. Costs are per camera sample "
          "(pixel sample) at the top spp, first seed. Device times are OpenCL profiling events, seconds summed over "
          "launches.", ""]
    head = []
    for r in results:
        sc = r["scene"]
        lad = r["ladder"]
        sums = {lab: summarise(rows, lad) for lab, rows in r["rows"].items()}
        base = efficiency(sums["delta-per-channel"], lad)
        L += [f"### {sc['title']}: `bench/scenes/{sc['name']}.json`", ""]
        st0 = next(iter(r["stats"].values()))
        L += [f"{st0['width']}x{st0['height']}, ladder {', '.join(map(str, lad))} spp. Reference: {r['ref']['spp']} spp "
              f"of {r['ref']['tracker']} ({r['ref']['seconds']:.0f} s render; RMSE of its own noise "
              f"{math.sqrt(max(r['var_ref'], 0)):.3g}; mean RGB {', '.join(f'{v:.4f}' for v in r['ref_mean'])}). "
              f"Plot: `bench/results/{sc['name']}_rmse_vs_time.png`.", ""]
        L += ["| tracker | RMSE @ " + " / ".join(map(str, lad)) + " spp | s @ top spp | MSE x s | efficiency vs delta-pc |",
              "|---|---|---|---|---|"]
        for lab, s in sums.items():
            m, t = s[lad[-1]]
            e = efficiency(s, lad)
            L.append(f"| {lab} | {' / '.join(fmt_e(math.sqrt(max(s[k][0], 0))) for k in lad)} | {t:.2f} | "
                     f"{fmt_e(m * t)} | **{e / base:.2f}x** |")
            head.append((sc, lab, e / base))
        mres = r.get("mitsuba")
        if mres:
            s = summarise(mres["rows"], lad)
            m, t = s[lad[-1]]
            e = efficiency(s, lad)
            L.append(f"| Mitsuba 3 volpath ({mres['variant']}) | {' / '.join(fmt_e(math.sqrt(max(s[k][0], 0))) for k in lad)} | "
                     f"{t:.2f} | {fmt_e(m * t)} | {e / base:.2f}x |")
        L += ["", "| tracker | lookups/sample (track + shadow) | lookups / delta-pc | real/sample | null/sample | "
                  "control/sample | DDA steps/sample | paths/s | device s: track / shadow / scatter / raygen / other |",
              "|---|---|---|---|---|---|---|---|---|"]
        ref_st = r["stats"]["delta-per-channel"]
        lk_ref = ref_st["density_lookups_tracking"] + ref_st["density_lookups_shadow"]
        for lab, st in r["stats"].items():
            n = st["width"] * st["height"] * st["spp"]
            lk = st["density_lookups_tracking"] + st["density_lookups_shadow"]
            k = {name: v["seconds"] for name, v in st.get("kernels", {}).items()}
            main = [k.get(x, 0.0) for x in ("k_track", "k_shadow", "k_scatter", "k_raygen")]
            other = sum(k.values()) - sum(main)
            L.append(f"| {lab} | {lk / n:.1f} ({st['density_lookups_tracking'] / n:.1f} + "
                     f"{st['density_lookups_shadow'] / n:.1f}) | {lk / lk_ref:.2f} | {st['real_collisions'] / n:.2f} | "
                     f"{st['null_collisions'] / n:.2f} | {st['control_collisions'] / n:.2f} | {st['dda_steps'] / n:.1f} | "
                     f"{st['paths_per_second']:.0f} | {' / '.join(f'{v:.2f}' for v in main)} / {other:.2f} |")
        if mres:
            a = mres["agree"]
            ours_lab = {"a": "spectral (history-average)", "b": "spectral-decomposition", "c": "delta"}[sc["key"]]
            ours = sums[ours_lab]
            mo, to = ours[lad[-1]]
            mm = s[lad[-1]][0]
            tm = s[lad[-1]][1]
            # RMSE at equal time: MSE x seconds is constant for an unbiased estimator, so Mitsuba's
            # RMSE at our top-spp time t is sqrt(MSE_m * t_m / t).
            rm_eq = math.sqrt(max(mm * tm / to, 0))
            L += ["", f"Mitsuba 3 side by side ({mres['variant']}, same grid, same machine, same run): at {to:.2f} s "
                      f"(our {ours_lab} at {lad[-1]} spp) our RMSE is {fmt_e(math.sqrt(max(mo, 0)))}, Mitsuba's "
                      f"{fmt_e(rm_eq)} (from its MSE x s at {lad[-1]} spp: {tm:.2f} s): ratio Mitsuba/ours "
                      f"{rm_eq / math.sqrt(max(mo, 1e-30)):.2f} in RMSE, {(mm * tm) / (mo * to):.2f} in efficiency.",
                  f"Agreement: Mitsuba at {a['spp']} spp (two halves, {a['seconds']:.0f} s) against our reference: "
                  f"MSE {fmt_e(a['mse'])}, expected from the two images' noise alone {fmt_e(a['expected'])} "
                  f"(ratio {a['mse'] / max(a['expected'], 1e-30):.2f}; 1 = agreement within noise); mean RGB Mitsuba "
                  f"{', '.join(f'{v:.4f}' for v in a['mean_mi'])} vs ours {', '.join(f'{v:.4f}' for v in a['mean_ref'])} "
                  f"(relative difference {', '.join(f'{100 * v:+.2f}%' for v in a['rel_mean_diff'])}, "
                  f"z = {', '.join(f'{v:+.1f}' for v in a['mean_z'])} standard errors); 8x8-pixel block means: MSE "
                  f"{fmt_e(a['block_mse'])} vs {fmt_e(a['block_expected'])} expected from noise (ratio "
                  f"{a['block_mse'] / max(a['block_expected'], 1e-30):.2f}); "
                  f"brightest Mitsuba pixel {a['max_mi']:.3g}; mirrored "
                  f"Mitsuba image MSE {fmt_e(a['flip_h_mse'])} (orientation check). Images: "
                  f"`bench/results/{sc['name']}_ours.png`, `bench/results/{sc['name']}_mitsuba.png`."]
            if mres.get("furnace"):
                L += ["", "White furnace on this grid (sigma_a = 0, sigma_s = the scene's sigma_t, environment 1, "
                          "no sun: every pixel is exactly 1), 16 spp x 4 seeds:", "",
                      "| renderer | mean RGB (4 seeds) | lowest / highest seed mean (R) | pixel min / max |",
                      "|---|---|---|---|"]
                for k, v in mres["furnace"].items():
                    L.append(f"| {k} | {', '.join(f'{x:.4f}' for x in v['mean'])} | {v['seed_min'][0]:.4f} / "
                             f"{v['seed_max'][0]:.4f} | {v['pixel_min']:.3g} / {v['pixel_max']:.3g} |")
        L.append("")
    if tp:
        L += ["### Kernel throughput (`build/kernel_throughput bench/scenes/cloud_chromatic.json`)", ""]
        for name, j in tp:
            L.append(f"- {name}: program build {j['seconds_program_build']:.2f} s "
                     f"({'from cache' if j['kernels_from_cache'] else 'compiled'}), first launches "
                     f"+{max(0, j['seconds_first_render'] - j['seconds_second_render']):.2f} s, kernel build total "
                     f"{j['seconds_kernel_build_total']:.2f} s.")
        j = tp[-1][1]
        L += ["", f"Warm run, device `{j['device']}`:", "",
              f"- density lookups (uniform points in the active box): {j['density']['lookups_per_second']:.3g}/s",
              f"- DDA cell steps (empty walk, density x 1e-9): {j['dda']['dda_steps_per_second']:.3g}/s "
              f"({j['dda']['dda_steps_per_path']:.1f} steps per ray)", "",
              "| tracker | free paths/s (central camera ray) | lookups/path | DDA steps/path | lookups/s |", "|---|---|---|---|---|"]
        for name, t in j["track"].items():
            L.append(f"| {name} | {t['paths_per_second']:.3g} | {t['lookups_per_path']:.2f} | {t['dda_steps_per_path']:.2f} | "
                     f"{t['lookups_per_second']:.3g} |")
        L.append("")
    return L, head


def headline(results):
    """The README's table and the targets, from the same numbers as the tables."""
    by = {r["scene"]["key"]: r for r in results}
    L = ["| scene | tracker | efficiency vs delta-per-channel | density lookups vs delta-per-channel | "
         "Mitsuba 3 RMSE / ours at equal time |", "|---|---|---|---|---|"]
    targets = []
    picks = {"a": ["spectral (history-average)", "spectral-decomposition", "decomposition"],
             "b": ["spectral (history-average)", "spectral-decomposition", "decomposition"],
             "c": ["delta", "spectral (history-average)", "spectral-decomposition"],
             "d": ["delta", "spectral (history-average)", "spectral-decomposition"]}
    for key, r in by.items():
        lad = r["ladder"]
        sums = {lab: summarise(rows, lad) for lab, rows in r["rows"].items()}
        base = efficiency(sums["delta-per-channel"], lad)
        st = r["stats"]
        lk = lambda lab: st[lab]["density_lookups_tracking"] + st[lab]["density_lookups_shadow"]
        mi_ratio = {}
        if r.get("mitsuba"):
            ms = summarise(r["mitsuba"]["rows"], lad)
            for lab in picks[key]:
                mo, to = sums[lab][lad[-1]]
                mm, tm = ms[lad[-1]]
                mi_ratio[lab] = math.sqrt(max(mm * tm / to, 0)) / math.sqrt(max(mo, 1e-30))
        for lab in picks[key]:
            e = efficiency(sums[lab], lad) / base
            L.append(f"| {r['scene']['title'].split(' ')[0]} {r['scene']['name']} | {lab} | {e:.2f}x | "
                     f"{lk(lab) / lk('delta-per-channel'):.2f} | {f'{mi_ratio[lab]:.2f}' if lab in mi_ratio else '-'} |")
        if key == "a":
            e = efficiency(sums["spectral (history-average)"], lad) / base
            targets.append(f"(a) spectral (history-average) efficiency vs delta-per-channel >= 2.7x: {e:.2f}x, "
                           f"{'met' if e >= 2.7 else f'missed by {2.7 / e:.2f}x'}")
        if key == "b":
            e = efficiency(sums["spectral-decomposition"], lad) / base
            targets.append(f"(b) spectral-decomposition efficiency vs delta-per-channel >= 4x: {e:.2f}x, "
                           f"{'met' if e >= 4 else f'missed by {4 / e:.2f}x'}")
            q = lk("decomposition") / lk("delta-per-channel")
            qt = st["decomposition"]["density_lookups_tracking"] / st["delta-per-channel"]["density_lookups_tracking"]
            targets.append(f"(b) decomposition density lookups <= 1/3 of delta tracking's (per channel, the same "
                           f"paths): {q:.2f} of them (tracking only: {qt:.2f}), "
                           f"{'met' if q <= 1 / 3 else f'missed by {q * 3:.2f}x'}")
        if key in ("a", "b") and mi_ratio:
            lab = "spectral (history-average)" if key == "a" else "spectral-decomposition"
            targets.append(f"({key}) lower RMSE than Mitsuba 3 at equal time ({lab}): Mitsuba's RMSE is "
                           f"{mi_ratio[lab]:.2f}x ours, {'met' if mi_ratio[lab] > 1 else 'missed'}")
    return L, targets


def splice(path, begin, end_marker, text):
    """Replaces the block from `begin` up to (not including) the next line starting with `end_marker`."""
    old = open(path).read() if os.path.exists(path) else ""
    lines = old.split("\n")
    if begin in lines:
        i = lines.index(begin)
        j = next((k for k in range(i + 1, len(lines)) if lines[k].startswith(end_marker)), len(lines))
        lines = lines[:i] + text.rstrip("\n").split("\n") + ([""] if j < len(lines) else []) + lines[j:]
    else:
        lines = lines + ([""] if lines and lines[-1] != "" else []) + text.rstrip("\n").split("\n") + [""]
    open(path, "w").write("\n".join(lines))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--device", default="")
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--scenes", default="abcd")
    ap.add_argument("--cache", default=os.path.expanduser("~/.cache/spectrack/bench"))
    ap.add_argument("--mitsuba-python", default="")
    ap.add_argument("--mitsuba-variant", default="llvm_ad_rgb")
    ap.add_argument("--no-results-md", action="store_true")
    args = ap.parse_args()
    if args.quick:
        args.seeds = min(args.seeds, 1)
    t_start = time.time()
    load_start = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    os.makedirs(args.cache, exist_ok=True)
    work = os.path.join(args.cache, "work")
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    # --quick never overwrites the committed results: its plots and tables go to the cache.
    results_dir = os.path.join(args.cache, "quick-results") if args.quick else os.path.join(ROOT, "bench", "results")
    os.makedirs(results_dir, exist_ok=True)
    codeh = code_digest()
    if not args.mitsuba_python:
        log("Mitsuba 3 not available (no --mitsuba-python): the side by side is skipped")

    # Kernel throughput: cold (empty spectrack and PoCL caches) then warm.
    tp = []
    tp_scene = os.path.join(ROOT, "bench", "scenes", "cloud_chromatic.json")
    tp_args = ["--points", str(1 << 18 if args.quick else 1 << 21), "--paths", str(1 << 14 if args.quick else 1 << 16)]
    if args.device:
        tp_args += ["--device", args.device]
    for name in ("cold", "warm"):
        env = dict(os.environ)
        if name == "cold":
            cold_dir = os.path.join(work, "cold-kernel-cache")
            env["SPECTRACK_KERNEL_CACHE_DIR"] = cold_dir
            env["POCL_KERNEL_CACHE"] = "0"
        out = os.path.join(work, f"throughput_{name}.json")
        log(f"kernel throughput ({name})")
        subprocess.run([os.path.join(ROOT, "build", "kernel_throughput"), tp_scene, "--json", out] + tp_args, env=env,
                       check=True)
        tp.append((name, json.load(open(out))))
    json.dump(dict(tp), open(os.path.join(results_dir, "kernel_throughput.json"), "w"), indent=1)

    results = []
    for sc in SCENES:
        if sc["key"] not in args.scenes:
            continue
        log(f"scene {sc['title']}")
        r = run_scene(sc, args, args.cache, codeh, work)
        results.append(r)
        plot(r, os.path.join(results_dir, f"{sc['name']}_rmse_vs_time.png"))
        if r.get("mitsuba"):
            ref = 0.5 * (np.load(os.path.join(r["ref"]["dir"], "half_1000.npy")) +
                         np.load(os.path.join(r["ref"]["dir"], "half_1001.npy")))
            save_png(ref, os.path.join(results_dir, f"{sc['name']}_ours.png"))
            save_png(r["mitsuba"]["mi_high"], os.path.join(results_dir, f"{sc['name']}_mitsuba.png"))
    dev = tp[-1][1]["device"]
    commit = subprocess.run(["git", "-C", ROOT, "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
    dirty = bool(subprocess.run(["git", "-C", ROOT, "status", "--porcelain", "--untracked-files=no"],
                                capture_output=True, text=True).stdout.strip())
    cpu = next((l.split(":", 1)[1].strip() for l in open("/proc/cpuinfo") if l.startswith("model name")), platform.processor())
    mem = next((int(l.split()[1]) for l in open("/proc/meminfo") if l.startswith("MemTotal")), 0) / 2 ** 20
    meta = dict(quick=args.quick, minutes=(time.time() - t_start) / 60, machine=f"{os.cpu_count()}-core {cpu}, {mem:.0f} GiB, "
                f"{platform.system()} {platform.release()}", device=dev, date=time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
                commit=commit, dirty=dirty, load_start=load_start.split("load average:")[-1].strip(),
                load_end=subprocess.run(["uptime"], capture_output=True, text=True).stdout.split("load average:")[-1].strip(),
                seeds=args.seeds)
    L, head = tables(results, tp, meta)
    H, targets = headline(results)
    L[8:8] = ["Headline (the README's table):", ""] + H + ["", "Targets:", ""] + [f"- {t}" for t in targets] + [""]
    notes = os.path.join(ROOT, "bench", "results", "issue4_notes.md")
    if os.path.exists(notes) and not args.quick:
        L += [open(notes).read().rstrip("\n"), ""]
    text = "\n".join(L) + "\n"
    open(os.path.join(results_dir, "issue4_results.md"), "w").write(text)
    raw = [dict(scene=r["scene"]["name"], ladder=r["ladder"], var_ref=r["var_ref"],
                ref={k: v for k, v in r["ref"].items() if k != "halves"},
                rows={k: {str(s): v for s, v in rows.items()} for k, rows in r["rows"].items()},
                mitsuba=None if not r.get("mitsuba") else dict(rows={str(s): v for s, v in r["mitsuba"]["rows"].items()},
                                                                agree=r["mitsuba"]["agree"],
                                                                furnace=r["mitsuba"].get("furnace")),
                stats=r["stats"]) for r in results]
    json.dump(dict(meta=meta, scenes=raw), open(os.path.join(results_dir, "issue4_raw.json"), "w"), indent=1)
    if not args.no_results_md and not args.quick:
        splice(os.path.join(ROOT, "bench", "results", "log_2026-12.md"), SECTION, "## ", text)
        readme = os.path.join(ROOT, "docs", "benchmarks.md")
        body = open(readme).read()
        b, e = "<!-- bench-headline:begin -->", "<!-- bench-headline:end -->"
        if b in body and e in body:
            block = "\n".join([b, f"Measured by `bench/run` on {meta['date']} ({meta['device']}, commit {meta['commit']}; "
                               "details in bench/results/log_2026-12.md):", ""] + H + [""] + [f"- {t}" for t in targets] + [e])
            body = body[:body.index(b)] + block + body[body.index(e) + len(e):]
            open(readme, "w").write(body)
    print(text)
    log(f"done in {(time.time() - t_start) / 60:.1f} min")


if __name__ == "__main__":
    main()
