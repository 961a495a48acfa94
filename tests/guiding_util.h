// guiding_util.h: helpers of the guiding tests (test_guiding*.cpp): a fixed-seed generator of
// 24-bit uniforms (the device's rng_uniform resolution), directions and frames in double,
// Gauss-Legendre quadrature over a lobe's polar variable, a host Henyey-Greenstein phase function
// (double precision, sampled exactly), the chi-square critical value, and the test mixtures.
#pragma once
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <random>
#include <vector>

#include "kernels/guiding.h"

namespace guiding_test {

constexpr double kPi = 3.14159265358979323846;

struct Uniforms {
  std::mt19937 gen;
  explicit Uniforms(uint32_t seed) : gen(seed) {}
  float next() { return float(gen() >> 8) * (1.0f / 16777216.0f); }
};

using D3 = std::array<double, 3>;

inline double dot(const D3& a, const D3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
inline D3 unit(double x, double y, double z) {
  double l = std::sqrt(x * x + y * y + z * z);
  return {x / l, y / l, z / l};
}
inline D3 to_d3(st_vec3 v) { return {v.x, v.y, v.z}; }
inline st_vec3 to_vec3(const D3& v) { return vec3_make(float(v[0]), float(v[1]), float(v[2])); }

// An orthonormal frame (t, b) around the unit vector n, in double (independent of vmf_frame).
inline void frame(const D3& n, D3& t, D3& b) {
  D3 a = std::fabs(n[0]) < 0.6 ? D3{1, 0, 0} : D3{0, 1, 0};
  double d = dot(a, n);
  t = unit(a[0] - d * n[0], a[1] - d * n[1], a[2] - d * n[2]);
  b = {n[1] * t[2] - n[2] * t[1], n[2] * t[0] - n[0] * t[2], n[0] * t[1] - n[1] * t[0]};
}

// The direction at 1 - cos theta = omc and azimuth phi around n.
inline D3 around(const D3& n, double omc, double phi) {
  D3 t, b;
  frame(n, t, b);
  double s = std::sqrt(std::max(0.0, omc * (2 - omc))), c = 1 - omc;
  D3 w;
  for (int a = 0; a < 3; ++a) w[a] = s * std::cos(phi) * t[a] + s * std::sin(phi) * b[a] + c * n[a];
  return w;
}

// 1 - cos of the angle between unit vectors, without cancellation: |a - b|^2 / 2.
inline double one_minus_cos(const D3& a, const D3& b) {
  double s = 0;
  for (int k = 0; k < 3; ++k) s += (a[k] - b[k]) * (a[k] - b[k]);
  return 0.5 * s;
}

// 16-point Gauss-Legendre nodes and weights on [-1, 1] (Golub-Welsch values, to 1e-15).
inline const std::array<std::array<double, 2>, 16>& gauss16() {
  static const std::array<std::array<double, 2>, 16> g = [] {
    std::array<std::array<double, 2>, 16> r{};
    const int n = 16;
    for (int i = 0; i < n; ++i) {  // Newton on P_16 from Chebyshev guesses
      double x = std::cos(kPi * (i + 0.75) / (n + 0.5)), dp = 0;
      for (int it = 0; it < 100; ++it) {
        double p0 = 1, p1 = x;
        for (int k = 2; k <= n; ++k) {
          double p2 = ((2 * k - 1) * x * p1 - (k - 1) * p0) / k;
          p0 = p1;
          p1 = p2;
        }
        dp = n * (x * p1 - p0) / (x * x - 1);
        double dx = p1 / dp;
        x -= dx;
        if (std::fabs(dx) < 1e-16) break;
      }
      r[i] = {x, 2 / ((1 - x * x) * dp * dp)};
    }
    return r;
  }();
  return g;
}

// Integral over [a, b] of f by 16-point Gauss-Legendre.
inline double gauss(double a, double b, const std::function<double(double)>& f) {
  double s = 0, h = 0.5 * (b - a), m = 0.5 * (a + b);
  for (auto& [x, w] : gauss16()) s += w * f(m + h * x);
  return s * h;
}

// Integral over the sphere of f(w) around the axis n, in t = 1 - cos theta on panels that halve
// toward t = 0 (down to 2^-40: a lobe of kappa 1e4 is resolved), and `n_phi` azimuths (the
// periodic trapezoid rule, exact for functions symmetric about n).
inline double sphere_integral_around(const D3& n, int n_phi, const std::function<double(const D3&)>& f) {
  double total = 0;
  for (int j = 0; j <= 40; ++j) {
    double hi = 2.0 * std::ldexp(1.0, -j), lo = j == 40 ? 0.0 : hi / 2;
    total += gauss(lo, hi, [&](double t) {
      double s = 0;
      for (int p = 0; p < n_phi; ++p) s += f(around(n, t, 2 * kPi * (p + 0.5) / n_phi));
      return s * 2 * kPi / n_phi;
    });
  }
  return total;
}

// The chi-square value exceeded with probability 1e-4 at `dof` degrees of freedom
// (Wilson-Hilferty; within 1% of the exact quantile above 30 degrees of freedom).
inline double chi2_critical_1e4(double dof) {
  const double z = 3.719016;
  double a = 2.0 / (9.0 * dof);
  return dof * std::pow(1 - a + z * std::sqrt(a), 3);
}

// Henyey-Greenstein in double: the value and an exact sampler around wo.
inline double hg(double g, double cos_theta) {
  double d = 1 + g * g - 2 * g * cos_theta;
  return (1 - g * g) / (4 * kPi * d * std::sqrt(d));
}
inline D3 hg_sample(double g, const D3& wo, double u1, double u2) {
  double s = (1 - g * g) / (1 - g + 2 * g * u1);
  double c = (1 + g * g - s * s) / (2 * g);
  return around(wo, 1 - c, 2 * kPi * u2);
}

// The integral over the sphere of f_HG(wo . w) g(w), in double (the reference of the estimators).
inline double phase_times_g(double g_hg, const D3& wo, const std::function<double(const D3&)>& g) {
  return sphere_integral_around(wo, 256, [&](const D3& w) { return hg(g_hg, dot(wo, w)) * g(w); });
}

// A mixture from (mean, kappa, weight) triples; the other lobes are unused.
struct LobeSpec {
  D3 mu;
  double kappa, weight;
};
inline st_vmf_mixture make_mixture(const std::vector<LobeSpec>& lobes) {
  st_vmf_mixture m{};
  for (int k = 0; k < ST_VMF_LOBES; ++k) m.lobe[k] = st_float4{0, 0, 1, 0};
  for (size_t k = 0; k < lobes.size(); ++k) {
    const LobeSpec& l = lobes[k];
    m.lobe[k] = st_float4{float(l.mu[0]), float(l.mu[1]), float(l.mu[2]), float(l.kappa)};
    m.weight[k] = float(l.weight);
  }
  return m;
}

}  // namespace guiding_test
