// devices.h: `spectrack devices`, the OpenCL platforms and devices this machine offers.
#pragma once

namespace spectrack {
int cmd_devices();
}  // namespace spectrack
