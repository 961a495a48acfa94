#!/usr/bin/env bash
# scale_out.sh [SCENE] [SPP] [REPEATS]: wall time of one frame rendered by one process, by
# `mpirun -np 1` and `-np 2` (`--mpi`), and by two contexts of the first device in one process
# (`--device 0:0,0:0`), interleaved REPEATS times (default 3) so that a change in machine load
# hits every configuration alike. Prints a markdown table of the median wall seconds and the ratio
# to one process, checks that every image equals the one-process image (oiiotool --diff, no
# value off by more than 1e-5), and prints the machine's load. Needs ./build/spectrack built with MPI.
set -euo pipefail
cd "$(dirname "$0")/.."
scene=${1:-data/scenes/cloud.json}
spp=${2:-64}
repeats=${3:-3}
bin=./build/spectrack
out=$(mktemp -d)
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
export OMPI_MCA_btl_vader_single_copy_mechanism=none OMPI_MCA_rmaps_base_oversubscribe=1
configs=("one process" "mpirun -np 1" "mpirun -np 2" "two contexts, one process")
run_config() {
  case "$1" in
    0) "$bin" render "$scene" --spp "$spp" -o "$out/c0.exr" --quiet ;;
    1) mpirun -np 1 "$bin" render "$scene" --spp "$spp" --mpi -o "$out/c1.exr" --quiet ;;
    2) mpirun -np 2 "$bin" render "$scene" --spp "$spp" --mpi -o "$out/c2.exr" --quiet ;;
    3) "$bin" render "$scene" --spp "$spp" --device 0:0,0:0 -o "$out/c3.exr" --quiet ;;
  esac
}
"$bin" render "$scene" --spp 1 -o "$out/warm.exr" --quiet  # kernels into the cache first
load_before=$(cut -d' ' -f1-3 /proc/loadavg)
for r in $(seq "$repeats"); do
  for c in 0 1 2 3; do
    t0=$EPOCHREALTIME
    run_config "$c"
    t1=$EPOCHREALTIME
    awk -v c="$c" -v a="$t0" -v b="$t1" 'BEGIN {printf "%d %.3f\n", c, b - a}' >> "$out/times"
  done
done
load_after=$(cut -d' ' -f1-3 /proc/loadavg)
echo "scene $scene, $spp spp, $repeats interleaved repeats, $(nproc) cores, $(date -u +%F), commit $(git rev-parse --short HEAD)"
echo "load average before: $load_before, after: $load_after"
echo
echo "| configuration | median wall s | / one process | image = one process (within 1e-5) |"
echo "|---|---|---|---|"
base=""
for c in 0 1 2 3; do
  med=$(awk -v c="$c" '$1 == c {print $2}' "$out/times" | sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}')
  [ -z "$base" ] && base=$med
  same=yes
  if [ "$c" != 0 ]; then
    oiiotool "$out/c0.exr" "$out/c$c.exr" --fail 1e-5 --hardfail 1e-5 --diff >/dev/null 2>&1 || same=NO
  fi
  echo "| ${configs[$c]} | $med | $(awk -v a="$med" -v b="$base" 'BEGIN {printf "%.2f", a / b}') | $same |"
done
rm -rf "$out"
