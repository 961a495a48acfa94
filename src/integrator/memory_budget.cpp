// memory_budget.cpp: see memory_budget.h.
#include "integrator/memory_budget.h"

#include <fmt/format.h>

#include <cstdlib>
#include <fstream>
#include <limits>
#include <sstream>

#include "util/error.h"
#include "util/option_text.h"

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

double host_memory_available() {
  if (const char* v = std::getenv("SPECTRACK_HOST_MEMORY"); v && *v) {  // a count of bytes, strictly
    int64_t b = 0;
    const std::string why = read_integer(v, 0, int64_t(1) << 60, &b);
    if (!why.empty()) throw Error(fmt::format("SPECTRACK_HOST_MEMORY: '{}' is not a count of bytes ({})", v, why));
    return double(b);
  }
  std::ifstream f("/proc/meminfo");
  std::string line;
  while (std::getline(f, line)) {
    if (line.rfind("MemAvailable:", 0) != 0) continue;
    std::istringstream in(line.substr(13));
    double kib = 0;
    if (in >> kib) return kib * 1024.0;
  }
  return std::numeric_limits<double>::infinity();
}

std::string host_memory_shortfall(double bytes) {
  const double available = host_memory_available();
  if (bytes <= available) return "";
  const char* set = std::getenv("SPECTRACK_HOST_MEMORY");
  return fmt::format("needs about {:.1f} MiB of host memory, but {:.1f} MiB are available{}", bytes / 1048576.0,
                     available / 1048576.0, set && *set ? " (SPECTRACK_HOST_MEMORY says so)" : "");
}

void check_host_memory(double bytes, const std::string& what, const std::string& advice) {
  const std::string shortfall = host_memory_shortfall(bytes);
  if (!shortfall.empty()) throw Error(fmt::format("{} {}; {}", what, shortfall, advice));
}

void check_env_map_memory(const std::string& context, int width, int height) {
  const double texels = double(width) * double(height);
  check_host_memory(texels * kEnvHostBytesPerTexel,
                    fmt::format("{}: a {}x{} environment map ({:g} bytes per texel while packed)", context, width,
                                height, kEnvHostBytesPerTexel),
                    "use a smaller map");
}

}  // namespace spectrack
