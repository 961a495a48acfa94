// rgb2spec_table: generates the RGB-to-spectrum coefficient table the library embeds
// (src/color/spectrum.h, src/color/rgb2spec_srgb.cpp).
//
//   rgb2spec_table OUT.bin [--res N] [--threads N]
//
// Design: the build runs this once (CMakeLists.txt): it fits the Jakob-Hanika sigmoid-polynomial
// coefficients of every colour of a res^3 grid per largest component with the project's fitter
// (make_rgb2spec_table: linear sRGB under CIE D65, the CIE 1931 observer of data/cie/) and writes
// the table in the format of serialize_rgb2spec_table. No table is copied from elsewhere; the
// output depends only on the CIE data and this code. It is written to OUT.tmp and renamed, so an
// interrupted build never leaves a partial table.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <fstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "color/spectrum.h"

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: rgb2spec_table OUT.bin [--res N] [--threads N]\n");
    return 2;
  }
  const std::string out = argv[1];
  int res = 64;
  int threads = std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
  for (int i = 2; i < argc; ++i) {
    const std::string a = argv[i];
    if ((a == "--res" || a == "--threads") && i + 1 < argc) {
      char* end = nullptr;
      const long v = std::strtol(argv[++i], &end, 10);
      if (*end != '\0' || v < 1 || v > 256) {
        std::fprintf(stderr, "rgb2spec_table: %s: '%s' is not an integer in [1, 256]\n", a.c_str(), argv[i]);
        return 2;
      }
      (a == "--res" ? res : threads) = static_cast<int>(v);
    } else {
      std::fprintf(stderr, "rgb2spec_table: unknown argument '%s'\n", a.c_str());
      return 2;
    }
  }
  try {
    const auto t0 = std::chrono::steady_clock::now();
    const spectrack::Rgb2SpecTable t = spectrack::make_rgb2spec_table(res, threads);
    const std::vector<char> bytes = spectrack::serialize_rgb2spec_table(t);
    {
      std::ofstream f(out + ".tmp", std::ios::binary | std::ios::trunc);
      f.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
      f.close();
      if (!f) throw std::runtime_error("cannot write " + out + ".tmp");
    }
    if (std::rename((out + ".tmp").c_str(), out.c_str()) != 0) throw std::runtime_error("cannot rename to " + out);
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::printf("rgb2spec_table: %s: res %d, %zu bytes, worst fit residual %.1e, %.1f s on %d threads\n", out.c_str(),
                res, bytes.size(), t.max_residual, s, threads);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "rgb2spec_table: %s\n", e.what());
    return 1;
  }
  return 0;
}
