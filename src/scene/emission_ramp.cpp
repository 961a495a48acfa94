// emission_ramp.cpp: a ramp from a grid's value to a colour, as the kernels' colour table
// (emission_ramp.h has the design).
#include "scene/emission_ramp.h"

#include <algorithm>
#include <cmath>
#include <cstring>

namespace spectrack {

namespace {
constexpr int kRampEntries = 4096;
}

std::array<double, 3> ramp_colour(const RampStops& stops, double v) {
  if (v <= stops.front().first) return stops.front().second;
  for (size_t i = 1; i < stops.size(); ++i) {
    if (v > stops[i].first) continue;
    const double f = (v - stops[i - 1].first) / (stops[i].first - stops[i - 1].first);
    std::array<double, 3> c;
    for (int k = 0; k < 3; ++k) c[k] = stops[i - 1].second[k] + f * (stops[i].second[k] - stops[i - 1].second[k]);
    return c;
  }
  return stops.back().second;
}

double pack_emission_ramp(st_medium& m, const RampStops& stops, double value_min, double value_max,
                          std::vector<uint32_t>& grid_words) {
  const double v_lo = std::min(value_min, 0.0), v_hi = std::max(value_max, v_lo + 1e-6);
  const double last = std::log(v_hi - v_lo + 1.0);  // ln T at the largest value
  const double per_warp = (kRampEntries - 1) / last;
  std::vector<float> table(size_t(kRampEntries) * 4, 0.0f);
  double peak = 0;
  for (int i = 0; i < kRampEntries; ++i) {
    const double v = std::exp(i / per_warp) - 1.0 + v_lo;
    const std::array<double, 3> c = ramp_colour(stops, std::min(v, v_hi));
    for (int k = 0; k < 3; ++k) {
      table[size_t(i) * 4 + k] = float(c[k]);
      peak = std::max(peak, c[k]);
    }
  }
  m.temperature = st_float4{1.0f, float(1.0 - v_lo), 0.5f, 0.0f};  // T = v - v_lo + 1 > cutoff 0.5; A = 0
  m.blackbody_table = st_float4{0.0f, float(per_warp), float(kRampEntries - 1), -1.0f};  // warp ln T
  m.blackbody_offset = uint32_t(grid_words.size());
  grid_words.resize(grid_words.size() + table.size());
  std::memcpy(grid_words.data() + m.blackbody_offset, table.data(), table.size() * sizeof(float));
  return peak;
}

}  // namespace spectrack
