#!/usr/bin/env bash
# bench/gpu.sh [OUT_DIR]: the GPU check (docs/benchmarks.md) in one command, sized for about 8
# minutes on a machine with an NVIDIA GPU and its OpenCL driver (the `device` tool's machines).
#   0. bundle: where .gpu/bundle.tar.xz exists (bench/gpu_bundle.py packs a build with every
#      library it loads, for machines without the Debian packages and no registry, such as the
#      device tool's), it is unpacked to /opt/spectrack-gpu and its programs put in build/; the
#      baked-in source path (the build's folder) and ../shared are linked to this checkout; NVIDIA's OpenCL
#      library gets an ICD file when none lists it;
#   1. build: scripts/setup.sh (installs the Debian packages it lacks, builds build/); where apt
#      cannot reach a mirror, an existing build/ is used as it is (SKIP_SETUP=1 forces that;
#      skipped where step 0 unpacked a bundle);
#   2. the device: GPU_DEVICE (P:D or a name substring) or else the first device of type GPU that
#      `spectrack devices` lists; without one the script stops with exit 2 and says so;
#   4. kernel throughput on bench/scenes/cloud_chromatic.json (lookups/s, trilinear and stochastic,
#      DDA steps/s, free paths/s, kernel build) there;
#   7. pbrt-v4's grid (bench/pbrt_grid.py's scene: the bundle's grid/, or its cache) in RGB and
#      spectral mode, GRID_SPP (256) samples x 4 seeds each: grid.tsv (seconds_render) and
#      grid_images.tar (the EXRs; bench/pbrt_grid.py's variance is taken from them where OIIO is);
#      with a bundle's spectrack_old (gpu_bundle.py --old), both binaries, interleaved;
#   5. paths/s of every bench scene and data/scenes/cloud.json at 16 spp with the default tracker,
#      trilinear and stochastic lookups, after a warm-up render each (the figure bench/RESULTS.md compares
#      with the 2-core PoCL rows of bench/RESULTS.md: target >= 50x);
#   6. bench/run --quick --no-mitsuba --device there (needs apt; skipped where a bundle was used);
#   8. the wavefront against the bundle's spectrack_old (gpu_bundle.py --old: f9c773d's binary):
#      paths/s of both (and of the new one's sized loop, SPECTRACK_LOOP=sized) at 16 spp on every
#      bench scene (WAVEFRONT_SPP; WAVEFRONT_SCENES picks some), interleaved, 2 rounds (wavefront.tsv, with
#      iterations, host_waits and occupancy), their ratios, the grid's ratio from step 7
#      (GRID_SPP, 256), and the registers of every kernel (registers.txt: the new binary's NVIDIA
#      build log with -cl-nv-verbose, and ptxas -v on both binaries' cached PTX where ptxas is;
#      registers_per_kernel.txt: one line per binary, path state layout, kernel and register count:
#      dense_chromatic, smoke1 and smoke1 with ray marching, whose k_shadow carries its fields); the new
#      binary runs in both path state layouts (spectrack: SoA, a GPU's default; spectrack_aos:
#      SPECTRACK_STATE_LAYOUT=aos), whose soa/aos paths/s ratio per scene decides the default;
#      STEPS="0 2 7 8" is this check alone (about 4 minutes); OUT_DIR=$OUT on the device machine
#      brings gpu.log, wavefront.tsv and registers.txt back for bench/results/;
#   9. the GPU peer: Mitsuba 3's cuda_ad_rgb (PEER_VARIANT) from .gpu/mitsuba.tar.xz
#      (bench/gpu_mitsuba_pack.py) beside spectrack on the bench scenes Mitsuba can express
#      (bench/gpu_peer.py render: a reference, then 64 and 256 spp x 2 seeds each, interleaved;
#      PEER_ARGS adds options); the images come back in peer_images.tar, and
#      `bench/gpu_peer.py score DIR` on this side prints the efficiency ratios;
#      STEPS="0 2 9" is the peer alone;
#  10. pbrt-v4's GPU build on the same GPU: .gpu/pbrt.tar.xz or its parts .gpu/pbrt.tar.xz.part*
#      (bench/gpu_pbrt_pack.py; the parts travel over successive runs of a warm machine), unpacked
#      to /opt/pbrt-gpu; `pbrt --gpu` and spectrack (RGB and spectral) on the grid (g 0.6) at
#      PBRT_SPP (256) and 4x that, PBRT_SEEDS (4) seeds, interleaved after warm-ups: pbrt_grid.tsv
#      (wall and seconds_render) and pbrt_images.tar come back, and `bench/pbrt_grid.py --score DIR`
#      on this side prints the efficiency from the variance over seeds and the marginal seconds
#      (4x spp less 1x: pbrt's CUDA and OptiX start-up left out as spectrack's kernel build is);
#      STEPS="0 2 10" is this peer alone; skipped (not a failure) without the pack;
#   3. the test suite on it, last (the longest): ctest with SPECTRACK_DEVICE set, or, from a
#      bundle, spectrack_tests itself in TEST_SHARDS (8) parallel gtest shards (ctest.log).
# Everything goes to OUT_DIR (default out/gpu-<UTC date>): gpu.log (all output), devices.txt,
# ctest.log, kernel_throughput.json, paths.tsv, grid.tsv, grid_images.tar, bench_quick.log. Each
# step's failure is recorded and the next step still runs; the exit status is 1 if any step
# failed. STEPS="0 2 5" runs a subset; TIMEOUT_TESTS (default 300 s) bounds the tests, TEST_FILTER
# (a gtest filter) picks some.
set -uo pipefail
cd "$(dirname "$0")/.."
OUT=${1:-out/gpu-$(date -u +%Y%m%dT%H%M%S)}
mkdir -p "$OUT"
OUT=$(cd "$OUT" && pwd)
STEPS=${STEPS:-"0 1 2 3 4 5 6 7 8 9 10"}
exec > >(tee "$OUT/gpu.log") 2>&1
status=0
step() { case " $STEPS " in *" $1 "*) return 0 ;; *) return 1 ;; esac; }
fail() { echo "gpu.sh: FAILED: $*"; status=1; }
echo "gpu.sh: $(date -u) on $(hostname), commit $(git rev-parse --short HEAD 2>/dev/null || echo unknown)"
command -v nvidia-smi >/dev/null && nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv

bundled=0
if step 0 && [ -f .gpu/bundle.tar.xz ] && { [ "${BUNDLE:-0}" = 1 ] || ! build/spectrack --version >/dev/null 2>&1; }; then
  B=/opt/spectrack-gpu
  rm -rf "$B" && mkdir -p "$B" && tar -xJf .gpu/bundle.tar.xz -C "$B" || { echo "gpu.sh: cannot unpack the bundle"; exit 1; }
  mkdir -p build data/volumes && cp "$B"/bin/* build/ && cp "$B"/volumes/* data/volumes/
  repo=$(pwd -P)
  # the programs hold the source path they were built in (tests: SPECTRACK_BINARY, data paths)
  src=$(cat "$B/source_dir" 2>/dev/null || echo /work/main)
  if [ "$repo" != "$src" ] && [ ! -e "$src" ]; then mkdir -p "$(dirname "$src")" && ln -s "$repo" "$src"; fi
  # ../shared/data/vdb beside the checkout (tests, bench scenes)
  if [ -d "$B/shared_vdb" ] && [ ! -e "$repo/../shared/data/vdb" ]; then
    mkdir -p "$repo/../shared/data" && ln -s "$B/shared_vdb" "$repo/../shared/data/vdb"
  fi
  if ! grep -qs nvidia /etc/OpenCL/vendors/*.icd; then
    lib=$(ldconfig -p | awk '/libnvidia-opencl\.so\.1/ {print $NF; exit}')
    [ -n "$lib" ] || lib=$(find /usr/local/nvidia /usr/lib /usr/lib64 /usr/local -name 'libnvidia-opencl.so*' 2>/dev/null | head -n 1)
    if [ -n "$lib" ]; then mkdir -p /etc/OpenCL/vendors && echo "$lib" > /etc/OpenCL/vendors/nvidia.icd
      echo "gpu.sh: NVIDIA OpenCL library $lib"
    else echo "gpu.sh: no libnvidia-opencl found"; fi
  fi
  bundled=1
  echo "gpu.sh: bundle unpacked to $B (repository $repo)"
fi

if step 1 && [ $bundled = 0 ]; then
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

if step 4; then
  build/kernel_throughput bench/scenes/cloud_chromatic.json --device "$DEV" --json "$OUT/kernel_throughput.json" ||
    fail "kernel_throughput"
fi

g=/opt/spectrack-gpu/grid/st_chromatic_g0.6.json  # a bundle's, else bench/pbrt_grid.py's cache
[ $bundled = 1 ] || g=${SPECTRACK_BENCH_CACHE:-$HOME/.cache/spectrack/bench}/pbrt-grid/st_chromatic_g0.6.json
g=${GRID_SCENE:-$g}
if step 7 && [ ! -f "$g" ]; then echo "gpu.sh: no grid scene $g (run bench/pbrt_grid.py once, or GRID_SCENE=...): step 7 skipped"
elif step 7; then
  mkdir -p "$OUT/grid"
  bins=(build/spectrack); [ -x build/spectrack_old ] && bins+=(build/spectrack_old)  # a bundle's --old
  printf 'binary\tmode\tseed\tspp\tseconds_render\tpaths_per_second\tdensity_lookups\n' > "$OUT/grid.tsv"
  for bin in "${bins[@]}"; do
    for mode in rgb spectral; do
      flags=(); [ $mode = spectral ] && flags=(--spectral)
      $bin render "$g" "${flags[@]}" --spp 4 -q --no-alpha -o "$OUT/grid/warm.exr" >/dev/null 2>&1 || fail "grid warm-up ($bin $mode)"
    done
  done
  for seed in 0 1 2 3; do
    for mode in rgb spectral; do
      for bin in "${bins[@]}"; do  # interleaved: new old new old
        flags=(); [ $mode = spectral ] && flags=(--spectral)
        tag=$(basename "$bin")_${mode}_$seed
        $bin render "$g" "${flags[@]}" --spp "${GRID_SPP:-256}" --seed $seed -q --no-alpha \
          -o "$OUT/grid/$tag.exr" --stats-json "$OUT/grid/$tag.json" || { fail "grid $tag"; continue; }
        python3 -c "
import json; j = json.load(open('$OUT/grid/$tag.json'))
print('\t'.join(str(x) for x in ['$(basename "$bin")', '$mode', $seed, ${GRID_SPP:-256}, j['seconds_render'], round(j['paths_per_second']), j['density_lookups']]))" >> "$OUT/grid.tsv"
      done
    done
  done
  rm -f "$OUT/grid/warm.exr"
  (cd "$OUT/grid" && tar -cf "$OUT/grid_images.tar" ./*.exr ./*.json) && rm -rf "$OUT/grid"
  cat "$OUT/grid.tsv"
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

if step 6 && [ $bundled = 0 ]; then
  bash bench/run --quick --no-mitsuba --device "$DEV" > "$OUT/bench_quick.log" 2>&1 || fail "bench/run --quick"
  tail -n 20 "$OUT/bench_quick.log"
fi
if step 3; then
  if [ $bundled = 1 ]; then
    # no ctest files travel with a bundle: the test binary itself, in parallel gtest shards
    n=${TEST_SHARDS:-8}
    # Two suites need what the bundle stubs out (gpu_bundle.py): Open MPI (CliMpi) and the image
    # readers OpenImageIO tries on a file it cannot identify (a stub segfaults in
    # CliHostileImages.ImagesThatWouldBeMisreadAreRefusedByName); they run with a real build.
    filter=${TEST_FILTER:-*-CliMpi.*:CliHostileImages.ImagesThatWouldBeMisreadAreRefusedByName}
    pids=()
    for ((k = 0; k < n; ++k)); do
      GTEST_TOTAL_SHARDS=$n GTEST_SHARD_INDEX=$k timeout "${TIMEOUT_TESTS:-300}" build/spectrack_tests --gtest_brief=1 --gtest_filter="$filter" \
        > "$OUT/tests_shard$k.log" 2>&1 &
      pids+=($!)
    done
    wait "${pids[@]}"  # (a bare wait would also wait for the tee of the log)
    cat "$OUT"/tests_shard*.log > "$OUT/ctest.log"; rm -f "$OUT"/tests_shard*.log
    grep -E "^\[  (PASSED|FAILED|SKIPPED) " "$OUT/ctest.log" | sort | uniq -c | sort -rn | head -n 60
    grep -q "FAILED" "$OUT/ctest.log" && fail "tests (see ctest.log)"
    [ "$(grep -c '^\[  PASSED  \]' "$OUT/ctest.log")" = "$n" ] || fail "a test shard did not finish (timeout or crash; see ctest.log)"
  else
    (cd build && timeout "${TIMEOUT_TESTS:-300}" ctest --output-on-failure -j "$(nproc)") > "$OUT/ctest.log" 2>&1 ||
      fail "ctest (see ctest.log)"
    tail -n 4 "$OUT/ctest.log"
  fi
fi

if step 8; then
  bins=(build/spectrack); [ -x build/spectrack_old ] && bins+=(build/spectrack_old)
  # registers: a build from source with NVIDIA's verbose log (the new binary), and ptxas on the
  # PTX each binary's kernel cache holds (NVIDIA's program binaries are PTX)
  # the new binary in both path state layouts (SPECTRACK_STATE_LAYOUT; SoA is a GPU's default)
  : > "$OUT/registers.txt"
  # NVIDIA's verbose build log is an option other OpenCL platforms refuse (PoCL in a dry run)
  nv_options=$(command -v nvidia-smi >/dev/null 2>&1 && echo -cl-nv-verbose || true)
  for bin in "${bins[@]}"; do
    layouts=(default); [ "$bin" = build/spectrack ] && layouts=(soa aos)
    for layout in "${layouts[@]}"; do
      tag=$(basename "$bin")_$layout
      kc="$OUT/kcache_$tag"; rm -rf "$kc"; mkdir -p "$kc"
      # k_shadow with ray marching's fields (a feature of its own) and without them
      for s in bench/scenes/dense_chromatic.json bench/scenes/smoke1.json "bench/scenes/smoke1.json --transmittance ray-marching"; do
        env $([ $layout != default ] && echo SPECTRACK_STATE_LAYOUT=$layout) SPECTRACK_KERNEL_CACHE_DIR="$kc" \
          ${nv_options:+SPECTRACK_CL_OPTIONS=$nv_options} SPECTRACK_CL_BUILD_LOG="$OUT/build_log_$tag.txt" \
          $bin render $s --spp 1 -q --no-alpha -o "$OUT/warm.exr" >/dev/null 2>&1 || fail "registers: $tag $s"
      done
      if command -v ptxas >/dev/null; then
        sm=$(nvidia-smi --query-gpu=compute_cap --format=csv,noheader 2>/dev/null | head -n 1 | tr -d .)
        for f in "$kc"/*.bin; do
          echo "== $tag $(basename "$f") (ptxas -v, sm_${sm:-90})" >> "$OUT/registers.txt"
          ptxas -v --gpu-name "sm_${sm:-90}" "$f" -o /dev/null 2>&1 | grep -E "Compiling entry|registers" >> "$OUT/registers.txt"
        done
      fi
      [ -f "$OUT/build_log_$tag.txt" ] &&
        { echo "== $tag, NVIDIA build log"; grep -E "Compiling entry|registers" "$OUT/build_log_$tag.txt"; } >> "$OUT/registers.txt"
    done
  done
  # registers of every kernel per layout (the build log's "Compiling entry" / "Used N registers" pairs)
  awk '/^== /{tag=$2; sub(/,$/, "", tag)} /Compiling entry/{match($0, /k_[a-z_]+/); k=substr($0, RSTART, RLENGTH)}
       /Used [0-9]+ registers/ && k != "" {match($0, /Used [0-9]+/); print "registers", tag, k, substr($0, RSTART + 5, RLENGTH - 5); k=""}' \
    "$OUT/registers.txt" | sort -u | tee "$OUT/registers_per_kernel.txt" | grep -E "k_(track|shadow|scatter|raygen|finish|escape) "
  printf 'binary\tscene\tround\tpaths_per_second\tseconds_render\titerations\thost_waits\toccupancy_mean\n' > "$OUT/wavefront.tsv"
  # variants: the new binary (chunked), f9c773d's, and the new one's sized loop (a CPU's)
  # and the new one with the AoS path state (spectrack_aos; the default on a GPU is SoA)
  variants=(spectrack); [ -x build/spectrack_old ] && variants+=(spectrack_old); variants+=(spectrack_sized spectrack_aos)
  run_variant() {  # variant args...
    local v=$1; shift
    case $v in
      spectrack_sized) SPECTRACK_LOOP=sized build/spectrack "$@" ;;
      spectrack_aos) SPECTRACK_STATE_LAYOUT=aos build/spectrack "$@" ;;
      *) build/$v "$@" ;;
    esac
  }
  for s in ${WAVEFRONT_SCENES:-bench/scenes/*.json}; do
    for v in "${variants[@]}"; do run_variant $v render "$s" --spp 1 -q --no-alpha -o "$OUT/warm.exr" >/dev/null 2>&1; done
    for round in 1 2; do
      for v in "${variants[@]}"; do
        run_variant $v render "$s" --spp "${WAVEFRONT_SPP:-16}" -q --no-alpha -o "$OUT/render.exr" --stats-json "$OUT/stats.json" >/dev/null 2>&1 ||
          { fail "wavefront $v $s"; continue; }
        python3 -c "
import json; j = json.load(open('$OUT/stats.json'))
print('\t'.join(str(x) for x in ['$v', '$(basename "$s" .json)', $round, round(j['paths_per_second']), j['seconds_render'], j['iterations'], j.get('host_waits', '-'), round(j['occupancy_mean'], 3)]))" >> "$OUT/wavefront.tsv"
      done
    done
  done
  rm -f "$OUT/warm.exr" "$OUT/render.exr" "$OUT/stats.json"
  cat "$OUT/wavefront.tsv"
  python3 - "$OUT" <<'PY'
import csv, os, statistics, sys
out = sys.argv[1]
rows = list(csv.DictReader(open(os.path.join(out, "wavefront.tsv")), delimiter="\t"))
def pps(rows, binary, key):
    return [float(r["paths_per_second"]) for r in rows if r["binary"] == binary and r[key[0]] == key[1]]
for scene in sorted({r["scene"] for r in rows}):
    new, old = pps(rows, "spectrack", ("scene", scene)), pps(rows, "spectrack_old", ("scene", scene))
    sized = pps(rows, "spectrack_sized", ("scene", scene))
    aos = pps(rows, "spectrack_aos", ("scene", scene))
    if new and aos:
        print(f"state layout {scene}: soa/aos paths/s {statistics.median(new) / statistics.median(aos):.2f}x "
              f"(soa {statistics.median(new):.0f}, aos {statistics.median(aos):.0f})")
    if new and old:
        print(f"wavefront {scene}: new/old paths/s {statistics.median(new) / statistics.median(old):.2f}x "
              f"(new {statistics.median(new):.0f}, old {statistics.median(old):.0f})"
              + (f"; sized loop/old {statistics.median(sized) / statistics.median(old):.2f}x" if sized else ""))
grid = os.path.join(out, "grid.tsv")
if os.path.exists(grid):
    g = list(csv.DictReader(open(grid), delimiter="\t"))
    for mode in ("rgb", "spectral"):
        new = [float(r["paths_per_second"]) for r in g if r["binary"] == "spectrack" and r["mode"] == mode]
        old = [float(r["paths_per_second"]) for r in g if r["binary"] == "spectrack_old" and r["mode"] == mode]
        if new and old:
            print(f"wavefront grid {mode}: new/old paths/s {statistics.median(new) / statistics.median(old):.2f}x "
                  f"({g[0]['spp']} spp)")
PY
fi

if step 9; then
  # Mitsuba 3 on the same GPU: .gpu/mitsuba.tar.xz (bench/gpu_mitsuba_pack.py) unpacked onto PYTHONPATH
  M=/opt/mitsuba-gpu py=${PEER_PYTHON:-python3} variant=${PEER_VARIANT:-cuda_ad_rgb}
  if [ -f .gpu/mitsuba.tar.xz ] && [ ! -d "$M/mitsuba" ]; then
    mkdir -p "$M" && tar -xJf .gpu/mitsuba.tar.xz -C "$M" || fail "peer: cannot unpack .gpu/mitsuba.tar.xz"
  fi
  export PYTHONPATH=$M${PYTHONPATH:+:$PYTHONPATH}
  if "$py" -c "import mitsuba as mi; mi.set_variant('$variant')"; then
    # shellcheck disable=SC2086 # PEER_ARGS: more options, word-split on purpose
    timeout "${TIMEOUT_PEER:-300}" "$py" bench/gpu_peer.py render "$OUT/peer" --device "$DEV" --variant "$variant" \
      --mitsuba-python "$py" ${PEER_ARGS:-} || fail "peer (bench/gpu_peer.py render)"
    tar -cf "$OUT/peer_images.tar" -C "$OUT" peer && rm -rf "$OUT/peer"
  else
    fail "peer: $py cannot load Mitsuba's $variant (carry .gpu/mitsuba.tar.xz: bench/gpu_mitsuba_pack.py)"
  fi
fi

if step 10; then
  # pbrt-v4's GPU build: the pack's parts joined in name order (bench/gpu_pbrt_pack.py)
  P=/opt/pbrt-gpu
  parts=$(ls .gpu/pbrt.tar.xz .gpu/pbrt.tar.xz.part* 2>/dev/null | sort -V || true)
  if [ ! -x "$P/bin/pbrt" ] && [ -n "$parts" ]; then
    mkdir -p "$P" && cat $parts | tar -xJ -C "$P" || fail "pbrt: cannot unpack $parts (every part carried?)"
  fi
  ps=$P/grid/chromatic_grid_g0.6_independent.pbrt
  if [ ! -x "$P/bin/pbrt" ] || [ ! -f "$g" ]; then
    echo "gpu.sh: no pbrt-v4 GPU pack in .gpu (bench/gpu_pbrt_pack.py) or no grid scene $g: step 10 skipped"
  else
    mkdir -p "$OUT/pbrt"
    n=${PBRT_SPP:-256}
    run_peer() {  # renderer spp seed: one render, its line in pbrt_grid.tsv
      local r=$1 spp=$2 seed=$3 tag=$1_$2_$3 t0 t1 sr=-
      t0=$(date +%s.%N)
      case $r in
        pbrt) (cd "$P/grid" && LD_LIBRARY_PATH=$P/lib "$P/bin/pbrt" --gpu --spp "$spp" --seed "$seed" --quiet \
                 --outfile "$OUT/pbrt/$tag.exr" "$ps") >/dev/null 2>"$OUT/pbrt/$tag.err" ;;
        spectrack_rgb | spectrack_spectral)
          build/spectrack render "$g" $([ "$r" = spectrack_spectral ] && echo --spectral) --spp "$spp" --seed "$seed" \
            -q --no-alpha -o "$OUT/pbrt/$tag.exr" --stats-json "$OUT/pbrt/$tag.json" >/dev/null 2>"$OUT/pbrt/$tag.err" ;;
      esac || { fail "pbrt step: $tag ($(tail -n 2 "$OUT/pbrt/$tag.err" | tr '\n' ' '))"; return; }
      t1=$(date +%s.%N)
      [ -f "$OUT/pbrt/$tag.json" ] && sr=$(python3 -c "import json; print(json.load(open('$OUT/pbrt/$tag.json'))['seconds_render'])")
      printf '%s\t%s\t%s\t%s\t%s\n' "$r" "$spp" "$seed" "$(python3 -c "print(round($t1 - $t0, 4))")" "$sr" >> "$OUT/pbrt_grid.tsv"
    }
    printf 'renderer\tspp\tseed\twall_s\tseconds_render\n' > "$OUT/pbrt_grid.tsv"
    renderers="pbrt spectrack_rgb spectrack_spectral"
    for r in $renderers; do run_peer $r 16 1000; done  # warm-ups (CUDA/OptiX start, kernel caches)
    sed -i '2,$d' "$OUT/pbrt_grid.tsv"
    for seed in $(seq 0 $((${PBRT_SEEDS:-4} - 1))); do
      for spp in $n $((4 * n)); do
        for r in $renderers; do run_peer $r $spp $seed; done  # interleaved
      done
    done
    rm -f "$OUT"/pbrt/*_1000.*
    (cd "$OUT/pbrt" && tar -cf "$OUT/pbrt_images.tar" ./*.exr ./*.json ./*.err) && rm -rf "$OUT/pbrt"
    cat "$OUT/pbrt_grid.tsv"
  fi
fi

echo "gpu.sh: done, status $status, results in $OUT"
exit $status
