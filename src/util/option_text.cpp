// option_text.cpp: see option_text.h.
#include "util/option_text.h"
#include "util/strings.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <tuple>
#include <vector>

namespace spectrack {

std::string read_integer(const std::string& text, int64_t lo, int64_t hi, int64_t* out) {
  const bool negative = !text.empty() && text[0] == '-' && lo < 0;
  const size_t digits = negative ? 1 : 0;
  if (text.size() == digits || text.find_first_not_of("0123456789", digits) != std::string::npos)
    return fmt::format("'{}' is not a decimal integer{}", text, lo < 0 ? "" : " (digits only)");
  if (text.size() > digits + 1 && text[digits] == '0')  // CLI11 would read it as octal
    return fmt::format("'{}' has a leading zero (CLI11 would read it as octal): write it without", text);
  int64_t v = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (ec == std::errc::result_out_of_range || v < lo || v > hi)
    return fmt::format("{} is outside [{}, {}]", text, lo, hi);
  if (ec != std::errc() || end != text.data() + text.size()) return fmt::format("'{}' is not a decimal integer", text);
  *out = v;
  return "";
}

// `text` split at `sep` into exactly `n` fields ("" for a field count other than n).
static std::vector<std::string> fields(const std::string& text, char sep) {
  std::vector<std::string> out(1);
  for (char c : text) {
    if (c == sep) out.emplace_back();
    else out.back() += c;
  }
  return out;
}

std::string check_spp_range(const std::string& text, int64_t* a, int64_t* b) {
  const std::string form = "expected A:B with 0 <= A < B <= 2^32 and B - A <= 2^24";
  const std::vector<std::string> f = fields(text, ':');
  if (f.size() != 2) return fmt::format("{}, got '{}'", form, text);
  int64_t x = 0, y = 0;
  for (auto [s, v, name] : {std::tuple{&f[0], &x, "A"}, std::tuple{&f[1], &y, "B"}}) {
    const std::string why = read_integer(*s, 0, int64_t(1) << 32, v);
    if (!why.empty()) return fmt::format("{}, got '{}': {} {}", form, text, name, why);
  }
  if (y <= x) return fmt::format("{}, got '{}': B is not above A", form, text);
  if (y - x > (int64_t(1) << 24)) return fmt::format("{}, got '{}': {} samples", form, text, y - x);
  *a = x, *b = y;
  return "";
}

std::string check_shutter(const std::string& text, std::array<double, 2>* out) {
  const std::string form = "expected OPEN:CLOSE in seconds with OPEN <= CLOSE";
  const std::vector<std::string> f = fields(text, ':');
  if (f.size() != 2) return fmt::format("{}, got '{}'", form, text);
  std::array<double, 2> v{};
  for (int k = 0; k < 2; ++k) {
    char* end = nullptr;
    v[k] = std::strtod(f[k].c_str(), &end);
    if (f[k].empty() || *end != '\0' || !std::isfinite(float(v[k])))
      return fmt::format("{}, got '{}': '{}' is not a finite number (as a float)", form, text, f[k]);
  }
  if (v[1] < v[0]) return fmt::format("{}, got '{}': CLOSE is before OPEN", form, text);
  if (!std::isfinite(float(v[1] - v[0]))) return fmt::format("{}, got '{}': CLOSE - OPEN is not finite", form, text);
  *out = v;
  return "";
}

std::string check_pixel_bounds(const std::string& text, std::array<int, 4>* out) {
  const std::string form = "expected x0,x1,y0,y1 with 0 <= x0 < x1 <= 65536 and 0 <= y0 < y1 <= 65536";
  const std::vector<std::string> f = fields(text, ',');
  if (f.size() != 4) return fmt::format("{}, got '{}'", form, text);
  static const char* names[4] = {"x0", "x1", "y0", "y1"};
  int64_t v[4];
  for (int k = 0; k < 4; ++k) {
    const std::string why = read_integer(f[k], 0, 65536, &v[k]);
    if (!why.empty()) return fmt::format("{}, got '{}': {} {}", form, text, names[k], why);
  }
  if (!(v[0] < v[1] && v[2] < v[3]))
    return fmt::format("{}, got '{}': the window is empty ({})", form, text, v[0] < v[1] ? "y0 >= y1" : "x0 >= x1");
  *out = {int(v[0]), int(v[1]), int(v[2]), int(v[3])};
  return "";
}

std::string check_frames(const std::string& text, long long* a, long long* b) {
  const std::string form = fmt::format("expected A:B with A <= B, frame numbers in [{}, {}] and at most {} frames",
                                       -kMaxFrameNumber, kMaxFrameNumber, kMaxFrames);
  const std::vector<std::string> f = fields(text, ':');
  if (f.size() != 2) return fmt::format("{}, got '{}'", form, text);
  int64_t x = 0, y = 0;
  for (auto [s, v, name] : {std::tuple{&f[0], &x, "A"}, std::tuple{&f[1], &y, "B"}}) {
    const std::string why = read_integer(*s, -kMaxFrameNumber, kMaxFrameNumber, v);
    if (!why.empty()) return fmt::format("{}, got '{}': {} {}", form, text, name, why);
  }
  if (y < x) return fmt::format("{}, got '{}': B is below A", form, text);
  if (y - x + 1 > kMaxFrames)
    return fmt::format("'{}' is {} frames; one --frames renders at most {} (split the sequence)", text, y - x + 1,
                       kMaxFrames);
  *a = x, *b = y;
  return "";
}

std::string read_number(const std::string& text, double lo, double hi, double* out) {
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (end == text.c_str() || *end != '\0' || !std::isfinite(v) || v < lo || v > hi)
    return fmt::format("{} is not a number in [{}, {}]", text, lo, hi);
  *out = v;
  return "";
}

std::string check_png_name(const std::string& text) {
  return lower_extension(text) == ".png" ? std::string() : "a preview is a PNG file (FILE.png), got '" + text + "'";
}

std::string check_not_blank(const std::string& text, const std::string& what) {
  const bool blank = std::all_of(text.begin(), text.end(), [](unsigned char c) { return std::isspace(c); });
  return blank ? "an empty " + what + " (leave the option out for the default)" : std::string();
}

}  // namespace spectrack
