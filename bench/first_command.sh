#!/usr/bin/env bash
# bench/first_command.sh [BRANCH]: times the README's first command as a new user meets it: a fresh
# `git clone` of BRANCH (default: the current one) into a temporary folder, no compiler cache
# (CCACHE_DISABLE=1; setup.sh configures no launcher but this one), an empty kernel cache and an
# empty PoCL cache, then `./scripts/render-default.sh`. Every compile goes through a launcher that
# logs its CPU seconds, so the report splits the CPU time into the build's files and the rest, and
# names the costliest files. Prints the wall time of each step (the script's own lines), the CPU
# time of the whole command (user + system: on a shared machine the wall time grows with the load,
# the CPU time does not), the load average before and after, and the render's statistics.
set -euo pipefail
cd "$(dirname "$0")/.."
branch=${1:-$(git rev-parse --abbrev-ref HEAD)}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
launcher="$work/ctime.sh"
cat >"$launcher" <<'EOF'
#!/usr/bin/env bash
out=""; prev=""
for a in "$@"; do [ "$prev" = "-o" ] && out="$a"; prev="$a"; done
TIMEFORMAT="%U %S %R"
{ time "$@" 2>&3; } 3>&2 2>"$CTIME_LOG.$$"
rc=$?
echo "$(cat "$CTIME_LOG.$$") $out" >>"$CTIME_LOG"
rm -f "$CTIME_LOG.$$"
exit $rc
EOF
chmod +x "$launcher"
git clone -q -b "$branch" "$(pwd)" "$work/clone"
mkdir -p "$work/kernels" "$work/pocl"
echo "first_command: $(git -C "$work/clone" log --oneline -1) on $(nproc) cores, $(date -u '+%Y-%m-%d %H:%M UTC')"
echo "first_command: load before: $(cut -d' ' -f1-3 /proc/loadavg)"
(
  cd "$work/clone"
  export CCACHE_DISABLE=1 SPECTRACK_KERNEL_CACHE_DIR="$work/kernels" POCL_CACHE_DIR="$work/pocl"
  export CTIME_LOG="$work/compiles.log"
  export CMAKE_ARGS="-DCMAKE_CXX_COMPILER_LAUNCHER=$launcher -DCMAKE_C_COMPILER_LAUNCHER=$launcher"
  /usr/bin/time -f "first_command: wall %e s, CPU %U s user + %S s system" ./scripts/render-default.sh 2>&1 |
    grep -v '^progress:\|^\[ *[0-9]*%\]'
)
echo "first_command: load after: $(cut -d' ' -f1-3 /proc/loadavg)"
awk '{u += $1; s += $2; n++} END {printf "first_command: %d compiles, CPU %.0f s user + %.0f s system\n", n, u, s}' "$work/compiles.log"
echo "first_command: the costliest compiles (CPU s user, file):"
sort -rn "$work/compiles.log" | head -8 | awk '{printf "  %6.1f  %s\n", $1, $4}'
python3 - "$work/clone/out/sunset_smoke.stats.json" <<'EOF'
import json, sys
j = json.load(open(sys.argv[1]))
keys = ["spp", "adaptive_mean_spp", "noise_target", "noise_error", "seconds_kernel_build", "seconds_render", "seconds_total"]
print("first_command: render " + ", ".join(f"{k} {j[k]:.4g}" if isinstance(j.get(k), float) else f"{k} {j.get(k)}" for k in keys if k in j))
EOF
