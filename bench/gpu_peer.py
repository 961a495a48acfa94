#!/usr/bin/env python3
"""gpu_peer.py: spectrack beside Mitsuba 3 on the same device, efficiency 1 / (MSE x seconds).

Two halves, so that the device machine needs no numpy and no OpenImageIO:

  gpu_peer.py render OUT_DIR [--scenes A,B] [--spp 64,256] [--seeds 1,2] [--ref-spp 4096]
                     [--device P:D|NAME] [--variant cuda_ad_rgb] [--mitsuba-python PY]
  gpu_peer.py score OUT_DIR

`render` (standard library only; bench/gpu.sh step 9 runs it on the GPU machine) writes, per
scene, a dense dump of the grid (build/grid_export), spectrack's reference as two independent
halves (seeds 1000 and 1001, REF_SPP / 2 each, the scene's own tracker), then the ladder: for each
seed, for each spp, spectrack and Mitsuba (bench/mitsuba_side.py, whose translation of the scene is
the one bench/run uses) one after the other, after warm-up renders of each (kernel caches; Mitsuba
compiles a kernel per sample count, so it warms up every rung).
Images are EXR files in OUT_DIR/<scene>/, seconds in OUT_DIR/<scene>/seconds.json: spectrack's
`seconds_render`, Mitsuba's wall clock around mi.render and the read-back to the host.

`score` (numpy and OpenImageIO, on the machine the files come back to) prints, per scene and
spp, each renderer's MSE against the reference minus the reference's own noise (the variance of
the mean of two independent halves, as bench/error_vs_time.py), its seconds, its efficiency and
the ratio ours / Mitsuba's, and the relative difference of Mitsuba's mean from the reference (a
bias shows there: its MSE includes it, as a user would see it).
"""
import argparse
import json
import os
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BIN = os.path.join(ROOT, "build", "spectrack")
# The bench scenes bench/mitsuba_side.py can express: one medium, a delta sun and a sky, HG or
# isotropic (dense_chromatic's and cloud_sunlit_dense's suns are disks, which Mitsuba lacks).
SCENES = ["cloud_chromatic", "dense_subsurface", "smoke_thin", "smoke1"]


def log(msg):
    print(f"[{time.strftime('%H:%M:%S')}] gpu_peer: {msg}", flush=True)


def ours(scene, spp, seed, out_dir, tag, device):
    exr, stats = os.path.join(out_dir, f"{tag}.exr"), os.path.join(out_dir, f"{tag}.json")
    cmd = [BIN, "render", scene, "--spp", str(spp), "--seed", str(seed), "-o", exr, "--stats-json", stats,
           "--quiet", "--no-alpha"]
    if device:
        cmd += ["--device", device]
    subprocess.run(cmd, check=True)
    seconds = json.load(open(stats))["seconds_render"]
    os.remove(stats)
    return seconds


def render_scene(name, a):
    scene = os.path.join(ROOT, "bench", "scenes", name + ".json")
    out = os.path.join(a.out_dir, name)
    os.makedirs(out, exist_ok=True)
    med = json.load(open(scene))["media"][0]
    vol = os.path.normpath(os.path.join(os.path.dirname(scene), med["file"]))
    grid = os.path.join(out, "grid")
    subprocess.run([os.path.join(ROOT, "build", "grid_export"), vol, med.get("grid", "density"), grid], check=True,
                   stdout=subprocess.DEVNULL)
    seconds = {}
    for seed in (1000, 1001):
        seconds[f"ref_{seed}"] = ours(scene, a.ref_spp // 2, seed, out, f"ref_{seed}", a.device)
    log(f"{name}: reference {a.ref_spp} spp in {seconds['ref_1000'] + seconds['ref_1001']:.2f} s")
    ours(scene, a.spp[0], 999, out, "warm", a.device)
    env = dict(os.environ, SPECTRACK=BIN)
    mitsuba = [a.mitsuba_python, os.path.join(ROOT, "bench", "mitsuba_side.py"), scene, grid, a.variant, out]
    # Mitsuba's kernels hold the sample count: one warm-up per rung of the ladder.
    subprocess.run(mitsuba + [f"{spp}:999" for spp in a.spp], check=True, env=env, stdout=subprocess.DEVNULL)
    for seed in a.seeds:
        for spp in a.spp:
            seconds[f"ours_{spp}_{seed}"] = ours(scene, spp, seed, out, f"ours_{spp}_{seed}", a.device)
            subprocess.run(mitsuba + [f"{spp}:{seed}"], check=True, env=env, stdout=subprocess.DEVNULL)
    mi_seconds = json.load(open(os.path.join(out, "timings.json")))
    for seed in a.seeds:
        for spp in a.spp:
            seconds[f"mi_{spp}_{seed}"] = mi_seconds[f"{spp}:{seed}"]
            log(f"{name} {spp} spp seed {seed}: ours {seconds[f'ours_{spp}_{seed}']:.3f} s, "
                f"Mitsuba {seconds[f'mi_{spp}_{seed}']:.3f} s")
    for f in ["grid.f32", "warm.exr"] + [f"mi_{spp}_999.exr" for spp in a.spp]:
        if os.path.exists(os.path.join(out, f)):
            os.remove(os.path.join(out, f))
    json.dump(dict(seconds=seconds, spp=a.spp, seeds=a.seeds, ref_spp=a.ref_spp, variant=a.variant),
              open(os.path.join(out, "seconds.json"), "w"), indent=1)


def read_exr(path):
    from error_vs_time import read_exr as read  # numpy and OpenImageIO: the scoring side only
    return read(path)


def score(a):
    import numpy as np
    print("| scene | spp | ours MSE | ours s | Mitsuba MSE | Mitsuba s | efficiency ours / Mitsuba | "
          "Mitsuba mean vs reference |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for name in sorted(os.listdir(a.out_dir)):
        d = os.path.join(a.out_dir, name)
        if not os.path.exists(os.path.join(d, "seconds.json")):
            continue
        meta = json.load(open(os.path.join(d, "seconds.json")))
        s = meta["seconds"]
        h0, h1 = read_exr(os.path.join(d, "ref_1000.exr")), read_exr(os.path.join(d, "ref_1001.exr"))
        ref, var_ref = 0.5 * (h0 + h1), float(np.mean((h0 - h1) ** 2) / 4.0)
        for spp in meta["spp"]:
            row = {}
            for who in ("ours", "mi"):
                imgs = [read_exr(os.path.join(d, f"{who}_{spp}_{seed}.exr")) for seed in meta["seeds"]]
                mse = float(np.mean([np.mean((i - ref) ** 2) for i in imgs])) - var_ref
                sec = float(np.mean([s[f"{who}_{spp}_{seed}"] for seed in meta["seeds"]]))
                bias = float(np.mean(imgs, axis=0).mean() / max(ref.mean(), 1e-30) - 1.0)
                row[who] = (mse, sec, bias)
            (mo, so, _), (mm, sm, bm) = row["ours"], row["mi"]
            ratio = (mm * sm) / (mo * so) if mo > 0 and so > 0 else float("nan")
            print(f"| {name} | {spp} | {mo:.3e} | {so:.3f} | {mm:.3e} | {sm:.3f} | {ratio:.2f}x | {100 * bm:+.2f}% |")
    print(f"(MSE: mean over seeds of the mean squared difference from spectrack's reference, less the reference's "
          f"own noise; Mitsuba variant {meta['variant']}; reference {meta['ref_spp']} spp)")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("what", choices=["render", "score"])
    ap.add_argument("out_dir")
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--spp", default="64,256")
    ap.add_argument("--seeds", default="1,2")
    ap.add_argument("--ref-spp", type=int, default=4096)
    ap.add_argument("--device", default="")
    ap.add_argument("--variant", default="cuda_ad_rgb")
    ap.add_argument("--mitsuba-python", default=sys.executable)
    a = ap.parse_args()
    a.spp = [int(x) for x in a.spp.split(",")]
    a.seeds = [int(x) for x in a.seeds.split(",")]
    if a.what == "score":
        return score(a)
    os.makedirs(a.out_dir, exist_ok=True)
    failed = []
    for name in a.scenes.split(","):
        try:
            render_scene(name, a)
        except subprocess.CalledProcessError as e:
            log(f"{name}: FAILED ({' '.join(e.cmd[:3])} ... exit {e.returncode}); the next scene still runs")
            failed.append(name)
    if failed:
        sys.exit(f"gpu_peer: failed on {', '.join(failed)}")


if __name__ == "__main__":
    main()
