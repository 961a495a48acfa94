// options.h: the checks of the command line's values (CLI11 validators: a bad value exits 2).
//
// Design: every number is read strictly here, before CLI11 converts it. CLI11 reads integers
// with strtoll/strtoull in base 0, so "010" would be 8, "0x10" 16, " 5" 5, and a value past
// 2^63 saturates; the options' own parsers used sscanf("%d"), which wraps 4294967312 to 16. So a
// number is decimal digits only (a leading '-' where negatives are allowed), read with
// std::from_chars, which reports overflow instead of wrapping, and then range-checked; the
// message names the value, the range and why. Each validator returns "" for a good value.
#pragma once
#include <CLI/CLI.hpp>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace spectrack {

// A decimal integer in [lo, hi]: "" and *out set, or the reason it is not.
std::string read_integer(const std::string& text, int64_t lo, int64_t hi, int64_t* out);
// An integer option's check (replaces CLI::Range, which lets wrapped and octal values through).
CLI::Validator integer_in(int64_t lo, int64_t hi);

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
// The CLI11 check of a --frames A:B value (render and info).
CLI::Validator frames_check();

// The value is one of `names`.
CLI::Validator one_of(const std::string& what, const std::vector<std::string>& names);
// A finite number in [lo, hi] (CLI::Range lets "nan" through: every comparison with NaN is false).
CLI::Validator finite_range(double lo, double hi);
// A preview is a .png (an EXR is written with -o).
CLI::Validator png_file();
// A value that is not empty nor only spaces (--device "" would silently mean the default).
CLI::Validator not_blank(const std::string& what);

}  // namespace spectrack
