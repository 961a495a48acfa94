// host_memory.h: the host's available physical memory, and the one message for a part that
// cannot fit it.
//
// Design: MemAvailable of /proc/meminfo is the figure (SPECTRACK_HOST_MEMORY, a count of bytes,
// stands in for it, so that tests can make a small case refuse); a refusal says how many MiB the
// part needs, how many are available and whether the variable set the figure. The render's own
// estimate (integrator/memory_budget.h) and the volume loaders (a NanoVDB grid's bytes, a quantized
// grid decoded as float) ask it before they allocate.
#pragma once
#include <string>

namespace spectrack {

// The host's available physical memory in bytes (SPECTRACK_HOST_MEMORY when set, else MemAvailable
// of /proc/meminfo; infinity when neither can be read).
double host_memory_available();

// "" where `bytes` fit host_memory_available(), else "needs about N MiB of host memory, but M MiB
// are available" (with "(SPECTRACK_HOST_MEMORY says so)" where that variable set the figure).
std::string host_memory_shortfall(double bytes);

// Throws Error "<what> needs about N MiB of host memory, but M MiB are available; <advice>" when
// `bytes` exceeds host_memory_available().
void check_host_memory(double bytes, const std::string& what, const std::string& advice);

}  // namespace spectrack
