// memory_budget.h: what a render will hold in memory, estimated before anything large is
// allocated, and the refusal when it cannot fit.
//
// Design: one table (memory_budget.cpp) gives the bytes each part of a render takes on the device
// and on the host: per texel of an environment map (its decoded texels, the packed float4 texels
// and sampling CDFs), per film pixel (the device film's sums and Kahan terms per layer, the double
// sums of the result and the channels written), per path slot (path state, shadow entries, queues)
// and per result value of the batch ring, plus the packed grids. The estimate is compared with the
// device's global memory and largest allocation (CL_DEVICE_GLOBAL_MEM_SIZE,
// CL_DEVICE_MAX_MEM_ALLOC_SIZE) and with the host's available physical memory (util/host_memory.h:
// MemAvailable of /proc/meminfo, or SPECTRACK_HOST_MEMORY, so that tests can make a small case
// refuse). A CPU device (PoCL) takes its global memory from the host, so there the device's
// share counts against the host as well. A refusal names the field or option that sizes the part,
// the figure and what is available.
#pragma once
#include <cstdint>
#include <string>

#include "util/host_memory.h"

namespace spectrack {

// Host bytes per texel of an environment map while it is packed: the decoded linear RGB floats
// (and the gray channel of a one-channel map) next to the packed float4 texel and its CDF entry.
constexpr double kEnvHostBytesPerTexel = 12.0 + 4.0 + 20.0;
// Device bytes per texel: the float4 texel and the conditional CDF entry (env_data).
constexpr double kEnvDeviceBytesPerTexel = 20.0;

// The sizes a render's estimate depends on (renderer.cpp fills them from its batch plan).
struct RenderShape {
  uint64_t npix = 0;            // pixels of the window
  uint64_t film_layers = 1;     // float4 sums per pixel on the device (result layers + moments)
  uint64_t aov_channels = 0;    // doubles per pixel of the film layers the result holds
  uint64_t path_slots = 0;      // Q
  uint64_t path_bytes = 0;      // bytes of one path slot's state and its shadow entries
  uint64_t queue_words = 0;     // 32-bit queue entries per path slot (both parities)
  uint64_t result_values = 0;   // float4 values of the batch result ring
  double scene_bytes = 0;       // the packed grids, majorants and environment maps on the device
};

struct MemoryNeed {
  double device = 0;  // bytes
  double host = 0;    // bytes the render adds on the host, the device's share excluded
  double film_device = 0, film_host = 0, slots_device = 0, results_device = 0;  // the parts, for messages
  double scene_device = 0;  // the packed scene's buffers, uploaded before the render's estimate
};

MemoryNeed render_memory(const RenderShape& s);

// The environment map of `context` ("scene.json: /lights/0/map"), `width` x `height` texels,
// checked before its pixels are read: its host share against the available memory.
void check_env_map_memory(const std::string& context, int width, int height);

}  // namespace spectrack
