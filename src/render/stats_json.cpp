// stats_json.cpp: see stats_json.h. One table of (key, member) pairs serves both directions.
#include "render/stats_json.h"

#include <utility>

namespace spectrack {

namespace {
using Counter = uint64_t RenderStats::*;
const std::pair<const char*, Counter> kCounters[] = {
    {"paths", &RenderStats::paths},
    {"density_lookups_tracking", &RenderStats::lookups_track},
    {"density_lookups_shadow", &RenderStats::lookups_shadow},
    {"emission_lookups", &RenderStats::lookups_emission},
    {"real_collisions", &RenderStats::real_collisions},
    {"null_collisions", &RenderStats::null_collisions},
    {"control_collisions", &RenderStats::control_collisions},
    {"residual_collisions", &RenderStats::residual_collisions},
    {"scatter_events", &RenderStats::scatter_events},
    {"dda_steps", &RenderStats::dda_steps},
    {"requeues", &RenderStats::requeues},
    {"iterations", &RenderStats::iterations},
    {"nonfinite_samples", &RenderStats::nonfinite_samples},
};
}  // namespace

nlohmann::json stats_to_json(const RenderStats& s) {
  nlohmann::json j;
  for (auto& [key, member] : kCounters) j[key] = s.*member;
  j["density_lookups"] = s.lookups_track + s.lookups_shadow;
  j["max_throughput"] = s.max_throughput;
  j["kernels"] = nlohmann::json::object();
  for (auto& [name, t] : s.kernels) j["kernels"][name] = {{"seconds", t.seconds}, {"launches", t.launches}};
  return j;
}

RenderStats stats_from_json(const nlohmann::json& j) {
  RenderStats s;
  for (auto& [key, member] : kCounters) s.*member = j.at(key).get<uint64_t>();
  s.max_throughput = j.at("max_throughput").get<double>();
  for (auto& [name, t] : j.at("kernels").items()) {
    s.kernels[name].seconds = t.at("seconds").get<double>();
    s.kernels[name].launches = t.at("launches").get<uint64_t>();
  }
  return s;
}

}  // namespace spectrack
