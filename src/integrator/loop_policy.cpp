// loop_policy.cpp: see loop_policy.h.
#include "integrator/loop_policy.h"

#include <fmt/format.h>

#include <algorithm>
#include <cstdlib>

#include "util/error.h"
#include "util/option_text.h"

namespace spectrack {

namespace {

constexpr uint64_t kGpuGroupsPerCu = 32;  // 2048 work-items of 64 per compute unit
constexpr uint64_t kCpuGroupsPerCu = 2;   // PoCL: one work-group per core at a time, and one to balance
// A CPU device runs the chunked loop too, its launches' work-items taking runs of their queue from
// its ticket counter (ST_ITEMS_GRABBED): on the idle machine that loop renders 1.07x the paths/s of
// the chunked loop with fixed runs (ST_ITEMS_BLOCKED; median of 20 interleaved pairs over five
// scenes) and 0.974x f9c773d's (30 pairs; the sized loop, one read per iteration: 0.968x), with at
// most 0.11 host waits per iteration (bench/results/quiet_2026-12-06.txt). Fixed runs left a core
// idle while the other finished its share of slower paths, and under load each launch waited for
// both cores (0.58x f9c773d's on dense_subsurface at load 14, bench/results/pocl_cost_2026-12-05c.txt);
// runs from a ticket go to whichever core asks, so a late work-group finds the queue taken.
constexpr bool kCpuSized = false;

const char* env(const char* name) {
  const char* e = std::getenv(name);
  return e && *e ? e : nullptr;
}

}  // namespace

LoopPolicy choose_loop_policy(cl_device_type type) {
  const bool gpu = (type & CL_DEVICE_TYPE_GPU) != 0;
  LoopPolicy p;
  p.groups_per_cu = gpu ? kGpuGroupsPerCu : kCpuGroupsPerCu;
  p.blocked_items = !gpu;
  p.grabbed_items = !gpu;
  p.sized = !gpu && kCpuSized;
  if (const char* e = env("SPECTRACK_LOOP")) {
    const std::string v = e;
    if (v != "chunked" && v != "sized")
      throw Error(fmt::format("SPECTRACK_LOOP: '{}' is not a stage loop (chunked or sized)", v));
    p.sized = v == "sized";
  }
  if (const char* e = env("SPECTRACK_STAGE_ITEMS")) {
    int64_t n = 0;  // strictly: decimal digits, no sign or space, no wrap past 2^32
    const std::string why = read_integer(e, 1, int64_t(1) << 32, &n);
    if (!why.empty()) throw Error(fmt::format("SPECTRACK_STAGE_ITEMS: '{}' is not a count of work-items ({})", e, why));
    p.items_forced = uint64_t(n);
  }
  if (const char* e = env("SPECTRACK_ITEM_ORDER")) {
    const std::string v = e;
    if (v != "grabbed" && v != "blocked" && v != "strided")
      throw Error(fmt::format("SPECTRACK_ITEM_ORDER: '{}' is not an item order (grabbed, blocked or strided)", v));
    p.blocked_items = v != "strided";
    p.grabbed_items = v == "grabbed";
  }
  return p;
}

uint64_t chunk_launch_items(const LoopPolicy& p, uint64_t cus, uint64_t local, uint64_t capacity) {
  const uint64_t device = p.items_forced > 0 ? p.items_forced : std::max<uint64_t>(1, cus) * p.groups_per_cu * local;
  return std::max<uint64_t>(1, std::min(capacity, device));
}

const char* loop_name(const LoopPolicy& p) { return p.sized ? "sized" : "chunked"; }
const char* item_order_name(const LoopPolicy& p) {
  return p.grabbed_items ? "grabbed" : p.blocked_items ? "blocked" : "strided";
}

void add_loop_policy_define(const LoopPolicy& p, std::vector<std::pair<std::string, std::string>>& defines) {
  if (p.blocked_items) defines.emplace_back("ST_ITEMS_BLOCKED", "1");
  if (p.grabbed_items) defines.emplace_back("ST_ITEMS_GRABBED", "1");
}

}  // namespace spectrack
