// options.cpp: see options.h.
#include "cli/options.h"

#include <fmt/format.h>


namespace spectrack {

CLI::Validator integer_in(int64_t lo, int64_t hi) {
  return CLI::Validator(
      [lo, hi](std::string& s) {
        int64_t v = 0;
        return read_integer(s, lo, hi, &v);
      },
      fmt::format("INT in [{}, {}]", lo, hi));
}

CLI::Validator one_of(const std::string& what, const std::vector<std::string>& names) {
  return CLI::Validator(
      [what, names](std::string& v) {
        for (auto& n : names)
          if (v == n) return std::string();
        std::string list;
        for (auto& n : names) list += (list.empty() ? "" : ", ") + n;
        return "unknown " + what + " '" + v + "' (one of: " + list + ")";
      },
      "NAME");
}

CLI::Validator frames_check() {
  return CLI::Validator(
      [](std::string& v) {
        long long a = 0, b = 0;
        return check_frames(v, &a, &b);
      },
      "A:B");
}

CLI::Validator finite_range(double lo, double hi) {
  return CLI::Validator(
      [lo, hi](std::string& s) {
        double v = 0;
        return read_number(s, lo, hi, &v);
      },
      fmt::format("NUMBER in [{}, {}]", lo, hi));
}

CLI::Validator png_file() {
  return CLI::Validator([](std::string& v) { return check_png_name(v); }, "FILE.png");
}

CLI::Validator not_blank(const std::string& what) {
  return CLI::Validator([what](std::string& v) { return check_not_blank(v, what); }, "TEXT");
}

}  // namespace spectrack
