// option_text.h: the strict readers of option values given as text (command-line flags).
//
// Design: every number is read strictly here, before CLI11 converts it. CLI11 reads integers
// with strtoll/strtoull in base 0, so "010" would be 8, "0x10" 16, " 5" 5, and a value past
// 2^63 saturates; sscanf("%d") would wrap 4294967312 to 16. So a number is decimal digits only (a
// leading '-' where negatives are allowed), read with std::from_chars, which reports overflow
// instead of wrapping, and then range-checked; the message names the value, the range and why.
// Each reader returns "" for a good value (and sets its outputs), else the reason. The settings
// table (integrator/option_table.h) checks its rows' values with these, the CLI's validators
// (cli/options.h) wrap them.
#pragma once
#include <array>
#include <cstdint>
#include <string>

namespace spectrack {

// A decimal integer in [lo, hi]: "" and *out set, or the reason it is not.
std::string read_integer(const std::string& text, int64_t lo, int64_t hi, int64_t* out);
// A finite number in [lo, hi] (NaN fails every comparison, so it is refused by name).
std::string read_number(const std::string& text, double lo, double hi, double* out);

// "A:B" with 0 <= A < B <= 2^32 and B - A <= 2^24 (--spp-range).
std::string check_spp_range(const std::string& text, int64_t* a, int64_t* b);
// "A:B", finite seconds with A <= B (--shutter: the shutter's open and close).
std::string check_shutter(const std::string& text, std::array<double, 2>* out);
// "x0,x1,y0,y1" with 0 <= x0 < x1 <= 65536 and 0 <= y0 < y1 <= 65536 (--pixel-bounds; the
// film's own size is checked later).
std::string check_pixel_bounds(const std::string& text, std::array<int, 4>* out);
// The most frames one --frames A:B renders, and the largest frame number.
constexpr long long kMaxFrames = 1000000;
constexpr long long kMaxFrameNumber = 999999999;
// "A:B" with -10^9 < A <= B < 10^9 and B - A + 1 <= kMaxFrames (--frames).
std::string check_frames(const std::string& text, long long* a, long long* b);
// A preview is a .png (an EXR is written with -o).
std::string check_png_name(const std::string& text);
// A value that is not empty nor only spaces ("" would silently mean the default); `what` names it.
std::string check_not_blank(const std::string& text, const std::string& what);

}  // namespace spectrack
