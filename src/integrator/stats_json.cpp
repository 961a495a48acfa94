// stats_json.cpp: see stats_json.h. RenderStats::counters() (key, member) serves both directions.
#include "integrator/stats_json.h"

namespace spectrack {

nlohmann::json stats_to_json(const RenderStats& s) {
  nlohmann::json j;
  for (auto& [key, member] : RenderStats::counters()) j[key] = s.*member;
  j["density_lookups"] = s.lookups_track + s.lookups_shadow;
  j["max_throughput"] = s.max_throughput;
  j["occupancy_mean"] = s.occupancy_mean;
  j["occupancy_min"] = s.occupancy_min;
  j["kernels"] = nlohmann::json::object();
  for (auto& [name, t] : s.kernels) j["kernels"][name] = {{"seconds", t.seconds}, {"launches", t.launches}};
  return j;
}

RenderStats stats_from_json(const nlohmann::json& j) {
  RenderStats s;
  for (auto& [key, member] : RenderStats::counters()) s.*member = j.at(key).get<uint64_t>();
  s.max_throughput = j.at("max_throughput").get<double>();
  s.occupancy_mean = j.at("occupancy_mean").get<double>();
  s.occupancy_min = j.at("occupancy_min").get<double>();
  for (auto& [name, t] : j.at("kernels").items()) {
    s.kernels[name].seconds = t.at("seconds").get<double>();
    s.kernels[name].launches = t.at("launches").get<uint64_t>();
  }
  return s;
}

}  // namespace spectrack
