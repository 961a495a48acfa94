// stage_table.h: the host's view of the wavefront's stage table (kernels/stage_types.h ST_STAGES):
// one row per stage, in launch order, with its kernel, the queue it reads, what that queue holds
// and when a render launches it. The launch list, kernel warm-up, the queue buffer's size, the
// launch sizes and the queue trace all come from here, so a new stage is a row in ST_STAGES and
// its stage function (kernels/stages.cl makes its kernel). Internal to src/integrator.
#pragma once
#include <cstdint>

#include "kernels/types.h"
#include "kernels/wavefront.h"

namespace spectrack {

struct Stage {
  const char* kernel;  // k_<stage>
  const char* name;    // <stage>, in the queue trace
  st_queue queue;
  st_queue_holds holds;
  st_stage_gate gate;
};

#define ST_X_HOST_STAGE(stage, QUEUE, HOLDS, GATE) \
  Stage{"k_" #stage, #stage, ST_Q_##QUEUE, ST_HOLDS_##HOLDS, ST_GATE_##GATE},
constexpr Stage kStages[] = {ST_STAGES(ST_X_HOST_STAGE)};
#undef ST_X_HOST_STAGE
static_assert(sizeof(kStages) / sizeof(kStages[0]) == ST_Q_COUNT, "one stage per queue");

// Whether a render of a scene with these features and lights launches the stage: without
// ST_FEATURE_ESCAPE track never queues an escape, without shadow-ray entries (lights, and the
// equi-angular entry: kernels/queues.h shadow_lights) nothing queues a shadow ray.
inline bool stage_launched(const Stage& s, uint32_t features, int shadow_entries) {
  switch (s.gate) {
    case ST_GATE_ESCAPE: return (features & ST_FEATURE_ESCAPE) != 0;
    case ST_GATE_LIGHTS: return shadow_entries > 0;
    default: return true;
  }
}

// Entries of the stage's queue (one parity): Q path slots, or Q * NL shadow-ray entries.
inline uint64_t queue_capacity(const Stage& s, uint64_t Q, uint64_t NL) {
  return s.holds == ST_HOLDS_SLOTS ? Q : Q * NL;
}

// Queue entries per path slot over both parities (memory sizing): each queue of path slots one,
// the shadow queue NL, twice.
inline uint64_t queue_words_per_slot(uint64_t NL) {
  uint64_t w = 0;
  for (const Stage& s : kStages) w += queue_capacity(s, 1, NL);
  return 2 * w;
}

}  // namespace spectrack
