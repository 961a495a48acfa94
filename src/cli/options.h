// options.h: the checks of the command line's values (CLI11 validators: a bad value exits 2).
//
// Design: CLI11 validators around the strict readers of util/option_text.h (which say why a
// value is refused); each returns "" for a good value. The settings table's rows
// (integrator/option_table.h) become flags through these (render_flags.cpp).
#pragma once
#include <CLI/CLI.hpp>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "util/option_text.h"

namespace spectrack {

// An integer option's check (replaces CLI::Range, which lets wrapped and octal values through).
CLI::Validator integer_in(int64_t lo, int64_t hi);

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
