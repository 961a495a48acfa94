// host_memory.cpp: see host_memory.h.
#include "util/host_memory.h"

#include <fmt/format.h>

#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <sstream>

#include "util/error.h"
#include "util/option_text.h"

namespace spectrack {

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

}  // namespace spectrack
