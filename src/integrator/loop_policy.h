// loop_policy.h: how the stage loop runs on a device type (docs/architecture.md, 'The stage loop
// on the device'). A GPU runs it in chunks of iterations, one host wait per chunk, each stage
// launched over 2048 work-items per compute unit, a work-item taking every G-th item of its queue
// (G the launch's work-items), so that neighbouring work-items read neighbouring entries. A CPU
// device runs it in chunks too (loop_policy.cpp says why), each launch two work-groups per core
// (PoCL runs a work-group on one core, its work-items one after another), so that the many
// near-empty launches of an iteration-heavy render's tail cost microseconds, and a work-item takes
// contiguous runs of its queue's items (ST_ITEMS_BLOCKED), so that a core goes through a queue in
// queue order, as a launch of one item per work-item does, from a ticket counter of the queue
// while any are left (ST_ITEMS_GRABBED), so that no core idles while another finishes a static
// share of slower paths. The sized loop (one read per iteration, each stage launched over its
// queue's items, none when empty) stays for measurements.
// SPECTRACK_LOOP=chunked|sized, SPECTRACK_STAGE_ITEMS=N (every chunked launch's work-items) and
// SPECTRACK_ITEM_ORDER=grabbed|blocked|strided override the choice, for measurements; any other
// value is an Error naming the variable.
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "device/opencl.h"

namespace spectrack {

struct LoopPolicy {
  bool sized = false;          // one read per iteration, each stage launched over its queue's items
  uint64_t groups_per_cu = 0;  // work-groups per compute unit of a chunked stage launch
  uint64_t items_forced = 0;   // SPECTRACK_STAGE_ITEMS: every chunked launch's work-items (0: per compute unit)
  bool blocked_items = false;  // a work-item takes a contiguous run of items (ST_ITEMS_BLOCKED)
  bool grabbed_items = false;  // stage work-items take runs from a ticket counter (ST_ITEMS_GRABBED)
};

LoopPolicy choose_loop_policy(cl_device_type type);
// Work-items of a chunked stage launch over a queue of this capacity, on cus compute units with
// work-groups of `local` work-items: the policy's, at most the capacity (rounded up to a
// work-group by the launcher), at least one.
uint64_t chunk_launch_items(const LoopPolicy& p, uint64_t cus, uint64_t local, uint64_t capacity);
// "chunked" or "sized"; "grabbed", "blocked" or "strided" (the stats JSON's stage_loop and item_order).
const char* loop_name(const LoopPolicy& p);
const char* item_order_name(const LoopPolicy& p);
// Adds the item order's kernel define to a program's defines (none for strided).
void add_loop_policy_define(const LoopPolicy& p, std::vector<std::pair<std::string, std::string>>& defines);

}  // namespace spectrack
