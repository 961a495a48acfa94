#!/usr/bin/python3
"""mitsuba_mis.py: spectrack's default tracker and spectral-mis against Mitsuba 3's `volpath` and
`volpathmis` (spectral MIS) on the bench scenes Mitsuba can render (one medium, no emission), in
one run: efficiency = 1 / (per-pixel variance x render seconds), the variance over --seeds renders
of --spp samples each, interleaved seed by seed (each renderer warmed first: PoCL's kernel JIT,
Dr.Jit's LLVM JIT, a warm-up render in the same process, not timed).

Usage (after bench/run has made the Mitsuba venv, or any Python with `mitsuba`):
  /usr/bin/python3 bench/mitsuba_mis.py --mitsuba-python VENV/bin/python [--variant llvm_ad_rgb]
      [--spp 8] [--seeds 4] [--scenes cloud_chromatic,dense_subsurface,smoke_thin,dense_chromatic]
Seconds: spectrack's seconds_render, Mitsuba's wall clock around mi.render (bench/mitsuba_side.py).
Variance only: a renderer's bias (Mitsuba's furnace on dense chromatic media is 1.5-3% low, see
bench/RESULTS.md) is not counted here; bench/error_vs_time.py measures MSE against a reference.
"""
import argparse
import json
import os
import shutil
import subprocess
import tempfile

import numpy as np
from error_vs_time import read_exr

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--mitsuba-python", required=True)
    ap.add_argument("--variant", default="llvm_ad_rgb")
    ap.add_argument("--spectrack", default=os.path.join(ROOT, "build", "spectrack"))
    ap.add_argument("--spp", type=int, default=8)
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--scenes", default="cloud_chromatic,dense_subsurface,smoke_thin,dense_chromatic")
    a = ap.parse_args()
    work = tempfile.mkdtemp(prefix="spectrack-mitsuba-mis.")
    try:
        for name in a.scenes.split(","):
            scene_path = os.path.join(ROOT, "bench", "scenes", name + ".json")
            scene = json.load(open(scene_path))
            med = scene["media"][0]
            vol = os.path.normpath(os.path.join(os.path.dirname(scene_path), med["file"]))
            prefix = os.path.join(work, name + "_grid")
            subprocess.run([os.path.join(ROOT, "build", "grid_export"), vol, med.get("grid", "density"), prefix],
                           check=True, capture_output=True)
            ours = {"spectrack default": [], "spectrack spectral-mis": ["--tracker", "spectral-mis"]}
            theirs = ["volpath", "volpathmis"]
            labels = list(ours) + [f"Mitsuba 3 {i}" for i in theirs]
            images = {k: [] for k in labels}
            secs = {k: [] for k in labels}

            def run_ours(label, seed):
                out = os.path.join(work, "o.exr")
                st = os.path.join(work, "o.json")
                subprocess.run([a.spectrack, "render", scene_path, "--spp", str(a.spp), "--seed", str(seed), "-o", out,
                                "--quiet", "--no-alpha", "--stats-json", st] + ours[label], check=True, capture_output=True)
                return read_exr(out), json.load(open(st))["seconds_render"]

            def run_theirs(integ, seed):
                out = os.path.join(work, "mi_" + integ)
                shutil.rmtree(out, ignore_errors=True)
                env = dict(os.environ, MITSUBA_INTEGRATOR=integ)
                p = subprocess.run([a.mitsuba_python, os.path.join(ROOT, "bench", "mitsuba_side.py"), scene_path,
                                    prefix, a.variant, out, f"{a.spp}:{900 + seed}", f"{a.spp}:{seed}"],
                                   env=env, capture_output=True, text=True)
                if p.returncode != 0:
                    raise SystemExit(f"mitsuba {integ} failed on {name}: {p.stderr[-1500:]}")
                t = json.load(open(os.path.join(out, "timings.json")))[f"{a.spp}:{seed}"]
                return read_exr(os.path.join(out, f"mi_{a.spp}_{seed}.exr")), t

            for label in ours:
                run_ours(label, 999)  # warm the kernel cache
            for seed in range(a.seeds):  # interleaved
                for label in ours:
                    im, t = run_ours(label, seed)
                    images[label].append(im)
                    secs[label].append(t)
                for integ in theirs:
                    im, t = run_theirs(integ, seed)
                    images[f"Mitsuba 3 {integ}"].append(im)
                    secs[f"Mitsuba 3 {integ}"].append(t)
            print(f"\n{name}, {a.spp} spp x {a.seeds} seeds, Mitsuba variant {a.variant}")
            print(f"{'renderer':26s} {'mean':>7s} {'variance':>10s} {'seconds':>8s} {'var x s':>10s}")
            vxs = {}
            for k in labels:
                ims = np.stack(images[k])
                var = float(np.mean(np.var(ims, axis=0, ddof=1)))
                t = float(np.mean(secs[k]))
                vxs[k] = var * t
                print(f"{k:26s} {float(np.mean(ims)):7.4f} {var:10.4e} {t:8.3f} {var * t:10.4e}")
            for k in ours:
                for integ in theirs:
                    m = f"Mitsuba 3 {integ}"
                    print(f"{k} vs {m}: {vxs[m] / vxs[k]:.2f}x its efficiency")
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
