// renderer_tables.cpp: what renderer.h declares besides the Renderer itself: the sum channels of
// the film layers, and RenderStats' list of counters (one X-macro table, types.h) and their sum.
#include "integrator/renderer.h"

#include <algorithm>

namespace spectrack {

std::vector<std::string> aov_sum_channels(uint32_t aovs) {
  std::vector<std::string> c;
  for (int k = 0; k < ST_AOV_COUNT; ++k) {
    if (!(aovs & (1u << k))) continue;
    if (k == ST_AOV_INDEX_ALPHA) c.insert(c.end(), {"AR", "AG", "AB"});  // A is their mean
    else if (k == ST_AOV_INDEX_VARIANCE) c.insert(c.end(), {"moment2.R", "moment2.G", "moment2.B"});
    else c.insert(c.end(), aov_exr_channels(k).begin(), aov_exr_channels(k).end());
  }
  if (aovs & (ST_AOV_BIT(ALBEDO) | ST_AOV_BIT(DEPTH))) c.push_back(kCollisionChannel);
  return c;
}

const std::vector<std::pair<const char*, RenderStats::Counter>>& RenderStats::counters() {
#define ST_X_DEVICE_ENTRY(E, field, key) {key, &RenderStats::field},
#define ST_X_HOST_ENTRY(field, key) {key, &RenderStats::field},
  static const std::vector<std::pair<const char*, Counter>> list = {ST_SUM_COUNTERS(ST_X_DEVICE_ENTRY)
                                                                        ST_HOST_COUNTERS(ST_X_HOST_ENTRY)};
  return list;
}

void RenderStats::add(const RenderStats& o) {
  // occupancy: the mean over all iterations of both, the minimum of both
  if (o.iterations > 0) {
    occupancy_min = iterations > 0 ? std::min(occupancy_min, o.occupancy_min) : o.occupancy_min;
    occupancy_mean = (occupancy_mean * double(iterations) + o.occupancy_mean * double(o.iterations)) /
                     double(iterations + o.iterations);
  }
  for (auto& [key, member] : counters()) this->*member += o.*member;
  max_throughput = std::max(max_throughput, o.max_throughput);
  for (auto& [name, t] : o.kernels) {
    kernels[name].seconds += t.seconds;
    kernels[name].launches += t.launches;
  }
}

}  // namespace spectrack
