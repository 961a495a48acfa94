#!/usr/bin/env bash
# bench/host_waits.sh OLD NEW: paths/s of two spectrack binaries on every bench scene and
# data/scenes/cloud.json, interleaved (A B, then B A, per round and seed) after a warm-up render of
# each (kernel caches), with the NEW binary's host waits (blocking reads and finishes in the stage
# loop, --stats-json host_waits) per iteration. SPP (4), ROUNDS (2), SEEDS ("0 1"), SCENES override.
# Prints one line per render, then per scene the NEW/OLD ratio of paths/s (min, median over the
# pairs) and host_waits / iterations; the last line is the ratio over every pair.
set -euo pipefail
OLD=${1:?OLD binary}; NEW=${2:?NEW binary}
cd "$(dirname "$0")/.."
echo "machine: $(nproc) cores, $(uptime)"
echo "commit: $(git rev-parse --short HEAD)$(git diff --quiet || echo ' (dirty)')  date: $(date -u +%FT%TZ)"
echo "OLD=$OLD NEW=$NEW SPP=${SPP:-4} ROUNDS=${ROUNDS:-2} SEEDS=${SEEDS:-0 1}"
python3 - "$OLD" "$NEW" <<'PY'
import json, os, statistics, subprocess, sys, tempfile
old, new = sys.argv[1], sys.argv[2]
spp, rounds = int(os.environ.get("SPP", "4")), int(os.environ.get("ROUNDS", "2"))
seeds = os.environ.get("SEEDS", "0 1").split()
scenes = os.environ.get("SCENES", " ".join(sorted(f"bench/scenes/{f}" for f in os.listdir("bench/scenes")
                                                  if f.endswith(".json")) + ["data/scenes/cloud.json"])).split()
tmp = tempfile.mkdtemp(prefix="spectrack-waits-")

def render(binary, scene, seed, n_spp):
    out = os.path.join(tmp, "stats.json")
    cmd = [binary, "render", scene, "--spp", str(n_spp), "--seed", seed, "-o", os.path.join(tmp, "out.exr"),
           "--stats-json", out, "--quiet", "--no-alpha"]
    p = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    if p.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed ({p.returncode}):\n{p.stderr}")
    return json.load(open(out))

all_ratios = []
summary = []
for scene in scenes:
    name = os.path.basename(scene)[:-5]
    render(old, scene, "0", 1); render(new, scene, "0", 1)
    ratios, waits = [], []
    for r in range(rounds):
        for seed in seeds:
            order = [("OLD", old), ("NEW", new)] if (r + seeds.index(seed)) % 2 == 0 else [("NEW", new), ("OLD", old)]
            pps = {}
            for tag, binary in order:
                j = render(binary, scene, seed, spp)
                pps[tag] = j["paths_per_second"]
                w = j.get("host_waits", "-")
                if tag == "NEW":
                    waits.append(j["host_waits"] / max(1, j["iterations"]))
                print(f"{name} round {r} seed {seed} {tag} paths/s {pps[tag]:.0f} seconds_render {j['seconds_render']:.3f} "
                      f"iterations {j['iterations']} host_waits {w}", flush=True)
            ratios.append(pps["NEW"] / pps["OLD"])
    all_ratios += ratios
    summary.append(f"{name}: NEW/OLD paths/s min {min(ratios):.3f} median {statistics.median(ratios):.3f} "
                   f"(pairs {len(ratios)}); host_waits per iteration max {max(waits):.3f}")
print()
print("\n".join(summary))
print(f"all scenes: NEW/OLD paths/s min {min(all_ratios):.3f} median {statistics.median(all_ratios):.3f} "
      f"(pairs {len(all_ratios)})")
PY
