// state_layout.h: the layout of the path state in device memory (kernels/path_state.h): AoS (one
// st_path per slot, the fields of a path side by side) or SoA (one array per field). The buffer
// is Q * sizeof(st_path) bytes either way; the kernels read it through the same group-wise loads
// and stores, and the layout is one kernel define (ST_STATE_SOA), part of the kernel source and
// so of the kernel cache key. The default follows the device type: AoS on a CPU (PoCL runs a
// work-item's loads as one struct's cache line; SoA measured no faster there, bench/RESULTS.md),
// SoA elsewhere (a GPU's warp then reads neighbouring values of one field; bench/gpu.sh measures
// both). SPECTRACK_STATE_LAYOUT=aos|soa forces one on every device.
#pragma once

#include "device/opencl.h"

#include <string>
#include <utility>
#include <vector>

namespace spectrack {

enum class StateLayout { aos, soa };

const char* state_layout_name(StateLayout l);
// The layout for a device of this type: SPECTRACK_STATE_LAYOUT if set (anything but aos or soa
// is an Error naming the variable), else the device type's default.
StateLayout choose_state_layout(cl_device_type type);
// Adds the layout's kernel define to a program's defines (none for AoS).
void add_state_layout_define(StateLayout l, std::vector<std::pair<std::string, std::string>>& defines);

}  // namespace spectrack
