// state_layout.cpp: see state_layout.h.
#include "integrator/state_layout.h"

#include <fmt/format.h>

#include <cstdlib>

#include "util/error.h"

namespace spectrack {

const char* state_layout_name(StateLayout l) { return l == StateLayout::soa ? "soa" : "aos"; }

StateLayout choose_state_layout(cl_device_type type) {
  if (const char* e = std::getenv("SPECTRACK_STATE_LAYOUT"); e && *e) {
    const std::string v = e;
    if (v == "aos") return StateLayout::aos;
    if (v == "soa") return StateLayout::soa;
    throw Error(fmt::format("SPECTRACK_STATE_LAYOUT: '{}' is not a path state layout (aos or soa)", v));
  }
  return (type & CL_DEVICE_TYPE_CPU) ? StateLayout::aos : StateLayout::soa;
}

void add_state_layout_define(StateLayout l, std::vector<std::pair<std::string, std::string>>& defines) {
  if (l == StateLayout::soa) defines.emplace_back("ST_STATE_SOA", "1");
}

}  // namespace spectrack
