// rgb2spec_srgb.cpp: the library's embedded RGB-to-spectrum table (spectrum.h rgb2spec_srgb).
//
// Design: the build generates the table (tools/rgb2spec_table.cpp, 9.4 MB at res 64: 3 x 64^3 x 3 floats) as a binary
// file and this file pulls it into .rodata with the assembler's .incbin (GCC and Clang on ELF), so
// no multi-megabyte array literal has to be compiled; RGB2SPEC_BIN is its path (CMakeLists.txt,
// which also makes this object depend on it). It is parsed and checked once, at first use.
#include <cstdint>
#include <stdexcept>
#include <string>

#include "color/spectrum.h"

#ifndef RGB2SPEC_BIN
#error "RGB2SPEC_BIN (the generated table's path) must be defined by the build"
#endif

asm(".section .rodata\n"
    ".balign 16\n"
    ".global spectrack_rgb2spec_srgb_begin\n"
    "spectrack_rgb2spec_srgb_begin:\n"
    ".incbin \"" RGB2SPEC_BIN "\"\n"
    ".global spectrack_rgb2spec_srgb_end\n"
    "spectrack_rgb2spec_srgb_end:\n"
    ".previous\n");
extern "C" const char spectrack_rgb2spec_srgb_begin[];
extern "C" const char spectrack_rgb2spec_srgb_end[];

namespace spectrack {

const Rgb2SpecTable& rgb2spec_srgb() {
  static const Rgb2SpecTable table = [] {
    Rgb2SpecTable t;
    std::string error;
    // two symbols, not one array: compare addresses, not pointers
    const std::size_t size = reinterpret_cast<std::uintptr_t>(spectrack_rgb2spec_srgb_end) -
                             reinterpret_cast<std::uintptr_t>(spectrack_rgb2spec_srgb_begin);
    if (!parse_rgb2spec_table(spectrack_rgb2spec_srgb_begin, size, t, &error))
      throw std::runtime_error("the embedded " + error + " (rebuild: " RGB2SPEC_BIN ")");
    return t;
  }();
  return table;
}

}  // namespace spectrack
