// rgb2spec_accuracy: how well the RGB-to-spectrum upsampling (src/color/spectrum.h) returns a
// colour: the embedded table alone (what a kernel's lookup gives) and fitted (scene constants),
// per band of the largest component, on a grid and on random colours; and the cost of each.
//
//   rgb2spec_accuracy [N_RANDOM]
//
// Design: every spectrum is integrated back to linear sRGB with the fitter's own 1 nm sums under
// D65, so the error is the upsampling's alone; colours come from a fixed-seed engine. Prints a
// Markdown table (bench/RESULTS.md "RGB upsampling").
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>

#include "color/spectrum.h"

using namespace spectrack;

int main(int argc, char** argv) {
  const int n_random = argc > 1 ? std::max(1, std::atoi(argv[1])) : 100000;
  const Rgb2SpecFit f;
  const Rgb2SpecTable& t = rgb2spec_srgb();
  std::mt19937_64 engine(7);
  auto uniform = [&] { return (engine() >> 11) * 0x1.0p-53; };
  auto err = [&](const RgbSpectrum& s, const Rgb& c) {
    const Rgb b = f.rgb_of(s);
    return std::max({std::fabs(b[0] - c[0]), std::fabs(b[1] - c[1]), std::fabs(b[2] - c[2])});
  };
  constexpr int kBands = 5;
  const double edges[kBands + 1] = {0, 0.5, 0.8, 0.9, 0.97, 1.0};
  double table_max[kBands] = {}, table_sum[kBands] = {}, fitted_max[kBands] = {};
  long count[kBands] = {};
  double table_s = 0, fitted_s = 0;
  for (int i = 0; i < n_random; ++i) {
    const Rgb c{uniform(), uniform(), uniform()};
    const double m = std::max({c[0], c[1], c[2]});
    int b = 0;
    while (b < kBands - 1 && m >= edges[b + 1]) ++b;
    auto t0 = std::chrono::steady_clock::now();
    const RgbSpectrum st = rgb2spec(t, c);
    auto t1 = std::chrono::steady_clock::now();
    const RgbSpectrum sf = rgb2spec_fitted(f, t, c);
    auto t2 = std::chrono::steady_clock::now();
    table_s += std::chrono::duration<double>(t1 - t0).count();
    fitted_s += std::chrono::duration<double>(t2 - t1).count();
    const double e = err(st, c);
    table_max[b] = std::max(table_max[b], e);
    table_sum[b] += e;
    fitted_max[b] = std::max(fitted_max[b], err(sf, c));
    ++count[b];
  }
  std::printf("table res %d (fit residual %.1e); %d random colours in [0, 1]^3, seed 7\n\n", t.res, t.max_residual,
              n_random);
  std::printf("| largest component | colours | table: mean error | table: max error | fitted: max error |\n|---|---|---|---|---|\n");
  for (int b = 0; b < kBands; ++b)
    std::printf("| [%.2f, %.2f) | %ld | %.2e | %.2e | %.2e |\n", edges[b], edges[b + 1], count[b],
                count[b] ? table_sum[b] / count[b] : 0.0, table_max[b], fitted_max[b]);
  std::printf("\nper colour: table lookup %.2f us, fitted %.1f us (host, one thread)\n", 1e6 * table_s / n_random,
              1e6 * fitted_s / n_random);
  return 0;
}
