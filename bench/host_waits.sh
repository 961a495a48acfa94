#!/usr/bin/env bash
# bench/host_waits.sh OLD NEW: paths/s of two spectrack binaries on every bench scene and
# data/scenes/cloud.json, interleaved (A B, then B A, per round and seed) after a warm-up render of
# each (kernel caches), with the NEW binary's host waits (blocking reads and finishes in the stage
# loop, --stats-json host_waits) per iteration. SPP (4), ROUNDS (2), SEEDS ("0 1"), SCENES override;
# OLD_ENV and NEW_ENV ("VAR=VALUE ...") set variables for one binary's renders only, so one binary
# can run against itself (NEW_ENV=SPECTRACK_LOOP=sized: the sized loop against the default).
# Prints one line per render (paths/s from seconds_render, the process's wall and CPU seconds:
# user + sys, of every thread, PoCL's included), then per scene the NEW/OLD ratio of paths/s and
# of CPU seconds (min, median over the pairs) and host_waits / iterations; the last lines are the
# ratios over every pair. On a shared machine the CPU seconds are the steadier figure: other
# processes stretch the wall time, not the CPU time a render takes.
set -euo pipefail
OLD=${1:?OLD binary}; NEW=${2:?NEW binary}
cd "$(dirname "$0")/.."
echo "machine: $(nproc) cores, $(uptime)"
echo "commit: $(git rev-parse --short HEAD)$(git diff --quiet || echo ' (dirty)')  date: $(date -u +%FT%TZ)"
echo "OLD=$OLD NEW=$NEW SPP=${SPP:-4} ROUNDS=${ROUNDS:-2} SEEDS=${SEEDS:-0 1} OLD_ENV=${OLD_ENV:-} NEW_ENV=${NEW_ENV:-}"
python3 - "$OLD" "$NEW" <<'PY'
import json, os, resource, statistics, subprocess, sys, tempfile, time
old, new = sys.argv[1], sys.argv[2]
spp, rounds = int(os.environ.get("SPP", "4")), int(os.environ.get("ROUNDS", "2"))
seeds = os.environ.get("SEEDS", "0 1").split()
scenes = os.environ.get("SCENES", " ".join(sorted(f"bench/scenes/{f}" for f in os.listdir("bench/scenes")
                                                  if f.endswith(".json")) + ["data/scenes/cloud.json"])).split()
tmp = tempfile.mkdtemp(prefix="spectrack-waits-")

def binary_env(name):  # "VAR=VALUE ..." from OLD_ENV or NEW_ENV
    return dict(kv.split("=", 1) for kv in os.environ.get(name, "").split())

def render(binary, scene, seed, n_spp, tag="OLD"):
    env = {**os.environ, **binary_env(tag + "_ENV")}
    out = os.path.join(tmp, "stats.json")
    cmd = [binary, "render", scene, "--spp", str(n_spp), "--seed", seed, "-o", os.path.join(tmp, "out.exr"),
           "--stats-json", out, "--quiet", "--no-alpha"]
    r0, t0 = resource.getrusage(resource.RUSAGE_CHILDREN), time.perf_counter()
    p = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, env=env)
    wall, r1 = time.perf_counter() - t0, resource.getrusage(resource.RUSAGE_CHILDREN)
    if p.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed ({p.returncode}):\n{p.stderr}")
    j = json.load(open(out))
    j["cpu_s"] = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
    j["wall_s"] = wall
    return j

all_ratios, all_cpu = [], []
summary = []
for scene in scenes:
    name = os.path.basename(scene)[:-5]
    render(old, scene, "0", 1, "OLD"); render(new, scene, "0", 1, "NEW")
    ratios, cpu_ratios, waits = [], [], []
    for r in range(rounds):
        for seed in seeds:
            order = [("OLD", old), ("NEW", new)] if (r + seeds.index(seed)) % 2 == 0 else [("NEW", new), ("OLD", old)]
            pps, cpu = {}, {}
            for tag, binary in order:
                j = render(binary, scene, seed, spp, tag)
                pps[tag] = j["paths_per_second"]
                cpu[tag] = j["cpu_s"]
                w = j.get("host_waits", "-")
                if tag == "NEW":
                    waits.append(j["host_waits"] / max(1, j["iterations"]))
                print(f"{name} round {r} seed {seed} {tag} paths/s {pps[tag]:.0f} seconds_render {j['seconds_render']:.3f} "
                      f"wall_s {j['wall_s']:.3f} cpu_s {j['cpu_s']:.3f} iterations {j['iterations']} host_waits {w}",
                      flush=True)
            ratios.append(pps["NEW"] / pps["OLD"])
            cpu_ratios.append(cpu["NEW"] / cpu["OLD"])
    all_ratios += ratios
    all_cpu += cpu_ratios
    summary.append(f"{name}: NEW/OLD paths/s min {min(ratios):.3f} median {statistics.median(ratios):.3f}; "
                   f"NEW/OLD CPU seconds median {statistics.median(cpu_ratios):.3f} max {max(cpu_ratios):.3f} "
                   f"(pairs {len(ratios)}); host_waits per iteration max {max(waits):.3f}")
print()
print("\n".join(summary))
print(f"all scenes: NEW/OLD paths/s min {min(all_ratios):.3f} median {statistics.median(all_ratios):.3f} "
      f"(pairs {len(all_ratios)})")
print(f"all scenes: NEW/OLD CPU seconds median {statistics.median(all_cpu):.3f} max {max(all_cpu):.3f}")
print(f"machine after: {os.getloadavg()} load average")
PY
