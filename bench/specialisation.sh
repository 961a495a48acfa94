#!/usr/bin/env bash
# specialisation.sh [REPEATS] [SECTIONS]: the specialisation measurements (docs/architecture.md, 'Kernels, the feature mask and the kernel cache') in one run, as markdown.
#   spec   specialised vs generic kernels (render seconds, interleaved, median of REPEATS) per scene
#   cache  kernel build cold (empty cache, POCL_KERNEL_CACHE=0) and warm, and seconds to the first finished pass of the
#          default scene (data/scenes/cloud.json) with a warm cache
#   maj    majorant study: cell 4/8/16 voxels, one level vs two levels (block 4 cells), per scene:
#          density lookups, DDA steps, steps into non-empty cells and microseconds per sample
#   occ    work distribution: 1, 2 and 8 (the default ring) batches of samples in flight
# SECTIONS is a comma list (default: spec,cache,maj,occ). Uses ./build/spectrack and python3;
# repeated runs are interleaved (A B A B ...) so that load from other processes hits both sides.
# Prints `uptime` first: other jobs on the machine make absolute seconds noisy, ratios less so.
set -euo pipefail
cd "$(dirname "$0")/.."
repeats=${1:-3}
sections=${2:-spec,cache,maj,occ}
echo "machine: $(nproc) cores, $(uptime)"
echo "commit: $(git rev-parse --short HEAD)$(git diff --quiet || echo ' (dirty)')  date: $(date -u +%FT%TZ)"
python3 - "$repeats" "$sections" <<'PY'
import json, os, statistics, subprocess, sys, tempfile, time
repeats, sections = int(sys.argv[1]), sys.argv[2].split(",")
tmp = tempfile.mkdtemp(prefix="spectrack-bench-")
cache = os.path.join(tmp, "kcache")
env = dict(os.environ, SPECTRACK_KERNEL_CACHE_DIR=cache)
scenes = ["data/scenes/cloud.json", "data/scenes/disney_cloud.json", "bench/scenes/dense_chromatic.json",
          "bench/scenes/smoke1.json"]
scenes = [s for s in scenes if os.path.exists(s)]

def render(scene, *args, spp=4, environ=None):
    out = os.path.join(tmp, "stats.json")
    t0 = time.time()
    p = subprocess.run(["./build/spectrack", "render", scene, "--spp", str(spp), "-o", os.path.join(tmp, "out.exr"),
                        "--stats-json", out, "--quiet", "--no-alpha", *args], env=environ or env, stderr=subprocess.PIPE, text=True)
    if p.returncode != 0:  # the compiler's warnings stay quiet unless the render fails
        sys.exit(f"render {scene} {' '.join(args)} failed ({p.returncode}):\n{p.stderr}")
    j = json.load(open(out))
    j["wall"] = time.time() - t0
    return j

def per_sample(j):
    return j["width"] * j["height"] * j["spp"]

if "spec" in sections:
    print("\n### Specialised vs generic kernels\n")
    print(f"median of {repeats} interleaved renders, 4 spp: render seconds (kernel build excluded) and the sum of "
          "the kernels' device time (OpenCL profiling); per-kernel columns: generic / specialised device time\n")
    print("| scene | features (hex) | specialised s | generic s | generic / specialised | device s spec. | device s gen. | device gen. / spec. | k_track | k_shadow | k_scatter |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for s in scenes:
        render(s); render(s, "--generic-kernels")  # warm the cache
        a, b, ka, kb, da, db = [], [], {}, {}, [], []
        for _ in range(repeats):
            ja = render(s); jb = render(s, "--generic-kernels")
            a.append(ja["seconds_render"]); b.append(jb["seconds_render"])
            da.append(sum(k["seconds"] for k in ja["kernels"].values()))
            db.append(sum(k["seconds"] for k in jb["kernels"].values()))
            for k in ("k_track", "k_shadow", "k_scatter"):
                ka.setdefault(k, []).append(ja["kernels"].get(k, {"seconds": 0})["seconds"])
                kb.setdefault(k, []).append(jb["kernels"].get(k, {"seconds": 0})["seconds"])
        ma, mb = statistics.median(a), statistics.median(b)
        kr = " | ".join(f"{statistics.median(kb[k]) / max(1e-9, statistics.median(ka[k])):.2f}x" for k in ka)
        mda, mdb = statistics.median(da), statistics.median(db)
        print(f"| {s} | {ja['features']:#x} | {ma:.3f} | {mb:.3f} | {mb / ma:.2f} | {mda:.3f} | {mdb:.3f} | "
              f"{mdb / mda:.2f} | {kr} |")

if "cache" in sections:
    print("\n### Kernel cache and first pass (data/scenes/cloud.json)\n")
    print("| run | kernel build s | from cache | first pass s (renderer) | first pass s (from CLI start) | process wall s (2 spp) |")
    print("|---|---|---|---|---|---|")
    for r in range(repeats):
        cold = os.path.join(tmp, f"cold{r}")
        # cold: an empty spectrack cache and PoCL's own kernel cache off (else PoCL serves the build);
        # warm: spectrack's cache only (PoCL still JIT-compiles each kernel for its work-group size
        # at the first launch, and caches that in its own kernel cache); warm + PoCL: both caches
        pocl = os.path.join(tmp, f"pocl{r}")
        for label, e in (("cold", dict(env, SPECTRACK_KERNEL_CACHE_DIR=cold, POCL_KERNEL_CACHE="0")),
                         ("warm", dict(env, SPECTRACK_KERNEL_CACHE_DIR=cold, POCL_CACHE_DIR=pocl)),
                         ("warm + PoCL cache", dict(env, SPECTRACK_KERNEL_CACHE_DIR=cold, POCL_CACHE_DIR=pocl))):
            j = render("data/scenes/cloud.json", spp=2, environ=e)
            print(f"| {label} #{r + 1} | {j['seconds_kernel_build']:.3f} | {j['kernels_from_cache']} | "
                  f"{j['seconds_first_pass']:.3f} | {j['seconds_first_pass_from_start']:.3f} | {j['wall']:.3f} |")

if "maj" in sections:
    print("\n### Majorant grid resolution\n")
    print(f"median seconds of {repeats} interleaved renders at 4 spp; counts per sample (camera path + its shadow rays)\n")
    print("| scene | cell | block | lookups/sample | DDA steps/sample | non-empty steps/sample | steps / non-empty | us/sample |")
    print("|---|---|---|---|---|---|---|---|")
    configs = [(c, b) for c in (4, 8, 16) for b in (0, 4)]
    for s in scenes:
        for c, b in configs:
            render(s, "--majorant-cell", str(c), "--majorant-block", str(b), spp=1)  # warm the cache
        rows = {cb: [] for cb in configs}
        for _ in range(repeats):
            for c, b in configs:
                rows[(c, b)].append(render(s, "--majorant-cell", str(c), "--majorant-block", str(b)))
        for (c, b), js in rows.items():
            j = js[0]
            n = per_sample(j)
            sec = statistics.median(x["seconds_render"] for x in js)
            ne = j["dda_steps_nonempty"]
            print(f"| {s} | {c} | {b} | {j['density_lookups'] / n:.1f} | {j['dda_steps'] / n:.1f} | {ne / n:.1f} | "
                  f"{j['dda_steps'] / max(1, ne):.2f} | {sec / n * 1e6:.2f} |")

if "occ" in sections:
    print("\n### Work distribution: batches in flight\n")
    print(f"median of {repeats} interleaved renders, 16 spp\n")
    print("| scene | batches in flight | render s | first pass s | iterations | mean occupancy | iterations < 50% busy |")
    print("|---|---|---|---|---|---|---|")
    for s in scenes[:1] + scenes[2:3]:
        rows = {k: [] for k in (1, 2, 8)}
        for _ in range(repeats):
            for k in rows:
                rows[k].append(render(s, "--batches-in-flight", str(k), spp=16))
        for k, js in rows.items():
            j = js[0]
            print(f"| {s} | {k} | {statistics.median(x['seconds_render'] for x in js):.3f} | "
                  f"{statistics.median(x['seconds_first_pass'] for x in js):.3f} | {j['iterations']} | "
                  f"{j['occupancy_mean']:.2f} | {j['iterations_below_half_occupancy']} |")
PY
