// noise.cpp: see noise.h.
#include "integrator/noise.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "util/error.h"

namespace spectrack {

NoiseEstimate estimate_noise(const double* sum, size_t sum_stride, const double* moment2, size_t moment2_stride,
                             size_t npix, int64_t n) {
  NoiseEstimate e;
  e.samples = n;
  if (n < 2) return e;
  e.measured = true;
  const double dn = double(n);
  std::vector<double> m, se;
  m.reserve(npix);
  se.reserve(npix);
  double total = 0;
  for (size_t i = 0; i < npix; ++i) {
    const double* s1 = sum + i * sum_stride;
    const double* s2 = moment2 + i * moment2_stride;
    double mean = 0, var = 0;
    for (int c = 0; c < 3; ++c) {
      mean += s1[c] / dn;
      var += std::max(0.0, (s2[c] - s1[c] * s1[c] / dn) / (dn * (dn - 1.0)));
    }
    mean /= 3.0;
    const double err = std::sqrt(var / 3.0);
    if (!(mean > 0.0) || !(err > 0.0) || !std::isfinite(err)) continue;
    m.push_back(mean);
    se.push_back(err);
    total += mean;
  }
  e.pixels = m.size();
  if (m.empty()) return e;
  const double floor = kNoiseFloor * total / double(m.size());
  std::vector<double> r(m.size());
  for (size_t i = 0; i < m.size(); ++i) r[i] = se[i] / std::max(m[i], floor);
  // the nearest-rank percentile: the smallest value with at least 95% of the pixels at or below it
  const size_t k = std::min(r.size() - 1, size_t(std::ceil(kNoisePercentile * double(r.size()))) - 1);
  std::nth_element(r.begin(), r.begin() + std::ptrdiff_t(k), r.end());
  e.error = r[k];
  return e;
}

NoiseEstimate estimate_film_noise(const std::vector<double>& sum, const std::vector<double>& aov_sum,
                                  const std::vector<std::string>& aov_channels, int64_t n) {
  const size_t na = aov_channels.size(), npix = sum.size() / 3;
  auto column = [&](const char* name) {
    for (size_t k = 0; k < na; ++k)
      if (aov_channels[k] == name) return int64_t(k);
    return int64_t(-1);
  };
  const int64_t m2 = column("moment2.R"), env = column("environment.R");
  if (m2 < 0) throw Error("internal: the noise of a film without its variance layer");
  std::vector<double> s1(sum);
  if (column("AR") >= 0 && env >= 0)  // a transparent film: the whole beauty's S1
    for (size_t i = 0; i < npix; ++i)
      for (int c = 0; c < 3; ++c) s1[i * 3 + c] += aov_sum[i * na + size_t(env) + c];
  return estimate_noise(s1.data(), 3, aov_sum.data() + m2, na, npix, n);
}

int64_t next_noise_check(double error, int64_t n, double target) {
  if (n < kNoiseMinSpp) return kNoiseMinSpp;
  // the error falls as 1 / sqrt(n): the target is predicted at n (error / target)^2
  const double predicted = target > 0 ? double(n) * (error / target) * (error / target) : 2.0 * double(n);
  const double next = std::clamp(std::ceil(predicted), double(n + 1), double(2 * n));
  return int64_t(next);
}

}  // namespace spectrack
