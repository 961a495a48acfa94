#!/usr/bin/env bash
# fuzz.sh [SECONDS]: builds the libFuzzer harnesses of tests/fuzz (clang, ASan + UBSan) in
# build-fuzz/ and runs them for SECONDS in all (default 60), split evenly: fuzz_scene (the scene
# loader, on a scratch copy of tests/fuzz/corpus/; the repository's corpus is never written),
# fuzz_vdb and fuzz_nvdb (the OpenVDB and NanoVDB loaders) and fuzz_image (the image reader), the
# last three on seeds that tests/fuzz/make_seeds.cpp writes with the project's own code. Exits
# non-zero on any finding: a crash, a sanitizer report, an exception other than spectrack::Error,
# a violated contract, a timeout (> 10 s for one input) or more than 2 GiB of memory. The input
# that triggered it is printed and kept in build-fuzz/findings/<harness>/; add it to the seeds
# once fixed. Extra arguments after SECONDS go to libFuzzer.
set -euo pipefail
cd "$(dirname "$0")/.."
SECS=${1:-60}
shift || true
if ! [[ "$SECS" =~ ^[0-9]+$ ]] || [ "$SECS" -lt 1 ]; then
  echo "usage: scripts/fuzz.sh [SECONDS] [libFuzzer flags...]" >&2
  exit 2
fi
SETUP_PACKAGES_ONLY=1 bash scripts/setup.sh

start=$(date +%s)
cmake -S . -B build-fuzz -DSPECTRACK_FUZZ=ON -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ >/dev/null
# FUZZ_HARNESSES="fuzz_scene fuzz_nvdb" runs a subset (the split stays SECONDS / count)
read -r -a HARNESSES <<<"${FUZZ_HARNESSES:-fuzz_scene fuzz_vdb fuzz_nvdb fuzz_image}"
cmake --build build-fuzz -j "${JOBS:-$(nproc)}" --target "${HARNESSES[@]}" make_seeds
echo "fuzz: built ${HARNESSES[*]} in build-fuzz/tests/fuzz in $(( $(date +%s) - start )) s"

rm -rf build-fuzz/findings  # only this run's findings are kept there
work=$(mktemp -d "${TMPDIR:-/tmp}/spectrack-fuzz.XXXXXX")
trap 'rm -rf "$work"' EXIT
mkdir "$work/seeds"
cp -R tests/fuzz/corpus "$work/seeds/scene"
build-fuzz/tests/fuzz/make_seeds "$work/seeds"
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1:symbolize=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
each=$(( SECS / ${#HARNESSES[@]} )); [ "$each" -ge 1 ] || each=1
failed=0
for h in "${HARNESSES[@]}"; do
  name=${h#fuzz_}
  mkdir -p "$work/artifacts/$name" "$work/tmp/$name"
  extra=()
  [ "$h" = fuzz_scene ] && extra=(-dict=tests/fuzz/scene.dict)
  asan=$ASAN_OPTIONS
  # OpenImageIO's PNG reader leaks a string when libpng longjmps out of a damaged file (31 bytes
  # per file, inside libOpenImageIO, whose frames the fast unwinder cannot see): not ours
  [ "$h" = fuzz_image ] && asan="$asan:detect_leaks=0"
  # OpenVDB leaks the nodes its readTopology allocated when a damaged file throws (lsan_openvdb.supp)
  lsan=${LSAN_OPTIONS:-}
  [ "$h" = fuzz_vdb ] && lsan="${lsan:+$lsan:}suppressions=$PWD/tests/fuzz/lsan_openvdb.supp"
  echo "fuzz: $h for $each s on $(ls "$work/seeds/$name" | wc -l) seeds"
  # A harness makes its scratch files under TMPDIR: keep them inside $work.
  set +e
  ASAN_OPTIONS="$asan" LSAN_OPTIONS="$lsan" TMPDIR="$work/tmp/$name" "build-fuzz/tests/fuzz/$h" -max_total_time="$each" -rss_limit_mb=2048 -timeout=10 \
    "${extra[@]}" -artifact_prefix="$work/artifacts/$name/" -print_final_stats=1 "$@" "$work/seeds/$name" \
    >"$work/$name.log" 2>&1
  rc=$?
  set -e
  tail -n 25 "$work/$name.log"
  shopt -s nullglob
  found=("$work/artifacts/$name"/*)
  shopt -u nullglob
  if [ $rc -ne 0 ] || [ ${#found[@]} -gt 0 ]; then
    failed=1
    # The tail above holds only the shadow-memory legend: print the report and its stacks too.
    echo "fuzz: $h report:"
    grep -m 1 -A 40 -E 'ERROR: |runtime error|==[0-9]+== ?ERROR|deadly signal|uncaught|contract' "$work/$name.log" |
      grep -v -E '^ *(Shadow|0x[0-9a-f]+:|=>0x)' || true
    mkdir -p "build-fuzz/findings/$name"
    for f in "${found[@]}"; do
      cp "$f" "build-fuzz/findings/$name/"
      echo "fuzz: finding build-fuzz/findings/$name/$(basename "$f") ($(wc -c <"$f") bytes), base64:"
      base64 -w 100 "$f" | head -c 20000; echo
    done
    echo "fuzz: $h FAILED (libFuzzer exit status $rc, ${#found[@]} finding(s)); reproduce with" \
         "build-fuzz/tests/fuzz/$h FILE" >&2
  else
    echo "fuzz: $h: no finding in $each s ($(ls "$work/seeds/$name" | wc -l) corpus entries at the end)"
  fi
done
exit $failed
