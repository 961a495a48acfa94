// memory_budget.cpp: see memory_budget.h.
#include "integrator/memory_budget.h"

#include <fmt/format.h>

#include "util/error.h"

namespace spectrack {

MemoryNeed render_memory(const RenderShape& s) {
  MemoryNeed n;
  const double px = double(s.npix);
  // device: per layer a float4 sum and its Kahan compensation per pixel
  n.film_device = px * double(s.film_layers) * 2.0 * 16.0;
  n.slots_device = double(s.path_slots) * (double(s.path_bytes) + 4.0 * double(s.queue_words));
  n.results_device = double(s.result_values) * 16.0;
  n.scene_device = s.scene_bytes;
  n.device = n.film_device + n.slots_device + n.results_device + s.scene_bytes;
  // host (the film is read back in chunks): the float image (12 B), the double sums of beauty and
  // layers in the result and again in the film piece written, and the float channels written
  n.film_host = px * (12.0 + 2.0 * (24.0 + 8.0 * double(s.aov_channels)) + 4.0 * (3.0 + double(s.aov_channels)));
  // the initial queue contents are staged on the host once
  n.host = n.film_host + double(s.path_slots) * 4.0 * double(s.queue_words);
  return n;
}

void check_env_map_memory(const std::string& context, int width, int height) {
  const double texels = double(width) * double(height);
  check_host_memory(texels * kEnvHostBytesPerTexel,
                    fmt::format("{}: a {}x{} environment map ({:g} bytes per texel while packed)", context, width,
                                height, kEnvHostBytesPerTexel),
                    "use a smaller map");
}

}  // namespace spectrack
