#!/usr/bin/env bash
# bench/gpu.sh [OUT_DIR]: the GPU check of issue 18 item 5 in one command, sized for about 8
# minutes on a machine with an NVIDIA GPU and its OpenCL driver (the `device` tool's machines).
#   1. build: scripts/setup.sh (installs the Debian packages it lacks, builds build/); where apt
#      cannot reach a mirror, an existing build/ is used as it is (SKIP_SETUP=1 forces that);
#   2. the device: GPU_DEVICE (P:D or a name substring) or else the first device of type GPU that
#      `spectrack devices` lists; without one the script stops with exit 2 and says so;
#   3. the kernel tests on it: ctest with SPECTRACK_DEVICE set (the host-only tests run too);
#   4. kernel throughput on bench/scenes/cloud_chromatic.json (lookups/s, trilinear and stochastic,
#      DDA steps/s, free paths/s, kernel build) there;
#   5. paths/s of every bench scene and data/scenes/cloud.json at 16 spp with the default tracker,
#      trilinear and stochastic lookups, after a warm-up render each (the figure issue 18 compares
#      with the 2-core PoCL rows of bench/RESULTS.md: target >= 50x);
#   6. bench/run --quick --no-mitsuba --device there.
# Everything goes to OUT_DIR (default out/gpu-<UTC date>): gpu.log (all output), devices.txt,
# ctest.log, kernel_throughput.json, paths.tsv, bench_quick.log. Each step's failure is recorded
# and the next step still runs; the exit status is 1 if any step failed. STEPS="1 3 5" runs a
# subset; TIMEOUT_TESTS (default 300 s) bounds ctest.
set -uo pipefail
cd "$(dirname "$0")/.."
OUT=${1:-out/gpu-$(date -u +%Y%m%dT%H%M%S)}
mkdir -p "$OUT"
OUT=$(cd "$OUT" && pwd)
STEPS=${STEPS:-"1 2 3 4 5 6"}
exec > >(tee "$OUT/gpu.log") 2>&1
status=0
step() { case " $STEPS " in *" $1 "*) return 0 ;; *) return 1 ;; esac; }
fail() { echo "gpu.sh: FAILED: $*"; status=1; }
echo "gpu.sh: $(date -u) on $(hostname), commit $(git rev-parse --short HEAD 2>/dev/null || echo unknown)"
command -v nvidia-smi >/dev/null && nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv

if step 1; then
  if [ "${SKIP_SETUP:-0}" != 1 ] && bash scripts/setup.sh; then :
  elif [ -x build/spectrack ]; then echo "gpu.sh: setup.sh did not complete: using the existing build/"
  else echo "gpu.sh: no build and setup.sh failed"; exit 1; fi
fi
[ -x build/spectrack ] || { echo "gpu.sh: build/spectrack is missing (run step 1)"; exit 1; }

build/spectrack devices | tee "$OUT/devices.txt"
DEV=${GPU_DEVICE:-$(awk '$0 ~ / GPU / {print $1; exit}' "$OUT/devices.txt")}
if [ -z "$DEV" ]; then
  echo "gpu.sh: no OpenCL GPU device is listed (is the vendor's OpenCL ICD installed?); GPU_DEVICE=... picks one"
  exit 2
fi
export SPECTRACK_DEVICE=$DEV
echo "gpu.sh: device $DEV"

if step 3; then
  (cd build && timeout "${TIMEOUT_TESTS:-300}" ctest --output-on-failure -j "$(nproc)") > "$OUT/ctest.log" 2>&1 ||
    fail "ctest (see ctest.log)"
  tail -n 4 "$OUT/ctest.log"
fi

if step 4; then
  build/kernel_throughput bench/scenes/cloud_chromatic.json --device "$DEV" --json "$OUT/kernel_throughput.json" ||
    fail "kernel_throughput"
fi

if step 5; then
  printf 'scene\tlookup\tpaths_per_second\tseconds_render\tdensity_lookups\tdevice\n' > "$OUT/paths.tsv"
  for s in bench/scenes/*.json data/scenes/cloud.json; do
    for lookup in trilinear stochastic; do
      build/spectrack render "$s" --lookup $lookup --spp 1 -q --no-alpha -o "$OUT/warm.exr" >/dev/null 2>&1 ||
        { fail "render $s ($lookup)"; continue; }
      build/spectrack render "$s" --lookup $lookup --spp 16 -q --no-alpha -o "$OUT/render.exr" --stats-json "$OUT/stats.json" ||
        { fail "render $s ($lookup)"; continue; }
      python3 -c "
import json; j = json.load(open('$OUT/stats.json'))
print('\t'.join(str(x) for x in ['$(basename "$s" .json)', '$lookup', round(j['paths_per_second']), j['seconds_render'], j['density_lookups'], j['device']]))" >> "$OUT/paths.tsv"
    done
  done
  rm -f "$OUT/warm.exr" "$OUT/render.exr" "$OUT/stats.json"
  cat "$OUT/paths.tsv"
fi

if step 6; then
  bash bench/run --quick --no-mitsuba --device "$DEV" > "$OUT/bench_quick.log" 2>&1 || fail "bench/run --quick"
  tail -n 20 "$OUT/bench_quick.log"
fi
echo "gpu.sh: done, status $status, results in $OUT"
exit $status
