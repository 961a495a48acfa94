// frames.h: frame patterns in file names, for sequences (`spectrack render --frames A:B`): a run
// of N '#' is the frame number zero-padded to N digits (smoke_######.vdb), and "$F<N>" likewise
// ("$F" alone: no padding), as in Houdini. Header-only (the scene loader and the CLI use it).
#pragma once
#include <cstdio>
#include <string>

namespace spectrack {

inline bool has_frame_pattern(const std::string& s) {
  return s.find('#') != std::string::npos || s.find("$F") != std::string::npos;
}

// `s` with every pattern replaced by `frame`.
inline std::string expand_frame(const std::string& s, long long frame) {
  std::string out;
  for (size_t i = 0; i < s.size();) {
    int width = -1;
    size_t next = i;
    if (s[i] == '#') {
      while (next < s.size() && s[next] == '#') ++next;
      width = int(next - i);
    } else if (s.compare(i, 2, "$F") == 0) {
      next = i + 2;
      width = 0;
      if (next < s.size() && s[next] >= '1' && s[next] <= '9') width = s[next++] - '0';
    }
    if (width < 0) {
      out += s[i++];
      continue;
    }
    char buf[32];
    std::snprintf(buf, sizeof(buf), "%0*lld", width, frame);
    out += buf;
    i = next;
  }
  return out;
}

}  // namespace spectrack
