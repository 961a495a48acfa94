#!/usr/bin/env bash
# fuzz.sh [SECONDS]: builds the scene-loader fuzzer (tests/fuzz/fuzz_scene.cpp: clang, libFuzzer,
# ASan + UBSan) in build-fuzz/ and runs it for SECONDS (default 60) on a scratch copy of
# tests/fuzz/corpus/ (the repository's corpus is never written). Exits non-zero on any finding:
# a crash, a sanitizer report, an exception other than spectrack::Error, a violated scene
# contract, a timeout (> 10 s for one input) or more than 2 GiB of memory. The input that
# triggered it is printed and kept in build-fuzz/findings/; add it to tests/fuzz/corpus/ once
# fixed. Extra arguments after SECONDS go to libFuzzer.
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
cmake --build build-fuzz -j "${JOBS:-$(nproc)}" --target fuzz_scene
echo "fuzz: built build-fuzz/tests/fuzz/fuzz_scene in $(( $(date +%s) - start )) s"

rm -rf build-fuzz/findings  # only this run's findings are kept there
work=$(mktemp -d "${TMPDIR:-/tmp}/spectrack-fuzz.XXXXXX")
trap 'rm -rf "$work"' EXIT
cp -R tests/fuzz/corpus "$work/corpus"
mkdir "$work/artifacts"
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1:symbolize=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
# The harness makes its scratch scene folder under TMPDIR: keep it inside $work.
set +e
TMPDIR="$work" build-fuzz/tests/fuzz/fuzz_scene -max_total_time="$SECS" -rss_limit_mb=2048 -timeout=10 \
  -dict=tests/fuzz/scene.dict -artifact_prefix="$work/artifacts/" -print_final_stats=1 "$@" "$work/corpus"
rc=$?
set -e
shopt -s nullglob
found=("$work"/artifacts/*)
if [ $rc -ne 0 ] || [ ${#found[@]} -gt 0 ]; then
  mkdir -p build-fuzz/findings
  for f in "${found[@]}"; do
    cp "$f" build-fuzz/findings/
    echo "fuzz: finding build-fuzz/findings/$(basename "$f") ($(wc -c <"$f") bytes), base64:"
    base64 -w 100 "$f" | head -c 20000; echo
  done
  echo "fuzz: FAILED (libFuzzer exit status $rc, ${#found[@]} finding(s)); reproduce with" \
       "build-fuzz/tests/fuzz/fuzz_scene FILE" >&2
  exit 1
fi
echo "fuzz: no finding in ${SECS} s ($(ls "$work/corpus" | wc -l) corpus entries at the end)"
