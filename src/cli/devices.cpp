// devices.cpp: `spectrack devices`: one line per OpenCL device (P:D index, name, type, compute
// units, memory, platform), in columns as wide as their longest entry.
#include "cli/devices.h"

#include <fmt/format.h>

#include <algorithm>
#include <iostream>

#include "device/opencl.h"

namespace spectrack {

int cmd_devices() {
  auto devs = enumerate_devices(true);
  if (devs.empty()) {
    std::cerr << "no OpenCL device found (install pocl-opencl-icd or a GPU driver)\n";
    return 1;
  }
  size_t wname = 6, wtype = 4;
  for (auto& d : devs) wname = std::max(wname, d.name.size()), wtype = std::max(wtype, std::string(d.type_name()).size());
  std::cout << fmt::format("{:<5} {:<{}} {:<{}} {:>4} {:>11} {:>11}  {}\n", "P:D", "device", wname, "type", wtype, "CUs",
                           "memory MiB", "max alloc", "platform");
  for (auto& d : devs)
    std::cout << fmt::format("{:<5} {:<{}} {:<{}} {:>4} {:>11} {:>11}  {} ({})\n",
                             fmt::format("{}:{}", d.platform_index, d.device_index), d.name, wname, d.type_name(), wtype,
                             d.compute_units, d.global_mem >> 20, d.max_alloc >> 20, d.platform_name, d.driver_version);
  return 0;
}

}  // namespace spectrack
