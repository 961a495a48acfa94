// blackbody.cpp: see blackbody.h.
#include "color/blackbody.h"

#include <algorithm>
#include <cmath>
#include <utility>

namespace spectrack {
namespace {

// CODATA 2018 (exact SI values for h, c, k)
constexpr double kH = 6.62607015e-34;
constexpr double kC = 299792458.0;
constexpr double kK = 1.380649e-23;
constexpr double kWienB = 2.897771955e-3;  // m K

using Mat3 = std::array<Rgb, 3>;

Rgb mul(const Mat3& m, const Rgb& v) {
  Rgb r{};
  for (int i = 0; i < 3; ++i) r[i] = m[i][0] * v[0] + m[i][1] * v[1] + m[i][2] * v[2];
  return r;
}

Mat3 inverse(const Mat3& m) {
  const double det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) -
                     m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
                     m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
  Mat3 r{};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      const int a = (j + 1) % 3, b = (j + 2) % 3, c = (i + 1) % 3, d = (i + 2) % 3;
      r[i][j] = (m[a][c] * m[b][d] - m[a][d] * m[b][c]) / det;
    }
  return r;
}

// Linear sRGB -> XYZ from the Rec.709 primaries and the D65 white (IEC 61966-2-1), Y of white = 1.
Mat3 srgb_to_xyz_matrix() {
  const double xy[4][2] = {{0.64, 0.33}, {0.30, 0.60}, {0.15, 0.06}, {0.3127, 0.3290}};
  auto XYZ = [&](int k) { return Rgb{xy[k][0] / xy[k][1], 1.0, (1 - xy[k][0] - xy[k][1]) / xy[k][1]}; };
  Mat3 P{};
  for (int k = 0; k < 3; ++k) {
    const Rgb c = XYZ(k);
    for (int i = 0; i < 3; ++i) P[i][k] = c[i];
  }
  const Rgb S = mul(inverse(P), XYZ(3));
  for (int i = 0; i < 3; ++i)
    for (int k = 0; k < 3; ++k) P[i][k] *= S[k];
  return P;
}

const Mat3& to_xyz() {
  static const Mat3 m = srgb_to_xyz_matrix();
  return m;
}
const Mat3& from_xyz() {
  static const Mat3 m = inverse(to_xyz());
  return m;
}

}  // namespace

double cie_y_integral() {
  static const double s = [] {
    double t = 0;
    for (const CieSample& c : kCie1931) t += c.y;
    return t;
  }();
  return s;
}

// log of planck(), finite for every T > 0: log(expm1(x)) = x + log1p(-exp(-x)) for large x
double log_planck(double lambda_nm, double T) {
  const double l = lambda_nm * 1e-9;
  const double x = kH * kC / (l * kK * T);
  const double log_em1 = x > 30 ? x + std::log1p(-std::exp(-x)) : std::log(std::expm1(x));
  return std::log(2 * kH * kC * kC * 1e-9) - 5 * std::log(l) - log_em1;
}

double planck(double lambda_nm, double T) {
  if (!(T > 0) || !(lambda_nm > 0)) return 0;
  return std::exp(log_planck(lambda_nm, T));  // W sr^-1 m^-3 x 1e-9 per nm; underflows to 0 when cold
}

double planck_peak_nm(double T) { return kWienB / T * 1e9; }

Rgb blackbody_xyz(double T, BlackbodyNorm norm, double* log_norm) {
  Rgb s{0, 0, 0};
  if (log_norm) *log_norm = 0;
  if (!(T > 0)) return s;
  // sums of B(lambda) / exp(ref): ref = log B(lambda_max) for peak, the largest log B over the
  // table for luminance (so a cold blackbody, far below double's range, keeps its colour)
  double ref = 0;
  if (norm == BlackbodyNorm::Peak) ref = log_planck(planck_peak_nm(T), T);
  if (norm == BlackbodyNorm::Luminance) {
    ref = -HUGE_VAL;
    for (const CieSample& c : kCie1931) ref = std::max(ref, log_planck(c.lambda_nm, T));
  }
  for (const CieSample& c : kCie1931) {
    const double b = std::exp(log_planck(c.lambda_nm, T) - ref);
    s[0] += b * c.x;
    s[1] += b * c.y;
    s[2] += b * c.z;
  }
  double n = 1.0 / cie_y_integral();
  if (norm == BlackbodyNorm::Luminance) n = 1.0 / s[1];
  // the spectrum is B / N with N = exp(ref) (peak, none), exp(ref) s_y / sum(y-bar) (luminance)
  if (log_norm) *log_norm = norm == BlackbodyNorm::Luminance ? ref + std::log(s[1] / cie_y_integral()) : ref;
  for (double& v : s) v *= n;
  return s;
}

namespace {
// max over 360..830 nm of B(lambda, T) / N, ln N = log_norm
double spectrum_max_of(double T, double log_norm) {
  const double lambda = std::clamp(planck_peak_nm(T), double(kCie1931[0].lambda_nm), double(kCie1931[kCieSamples - 1].lambda_nm));
  return std::exp(log_planck(lambda, T) - log_norm);
}
}  // namespace

double blackbody_spectrum_max(double T, BlackbodyNorm norm) {
  if (!(T > 0)) return 0;
  double log_norm = 0;
  blackbody_xyz(T, norm, &log_norm);
  return spectrum_max_of(T, log_norm);
}

Rgb xyz_to_linear_srgb(const Rgb& xyz) { return mul(from_xyz(), xyz); }
Rgb linear_srgb_to_xyz(const Rgb& rgb) { return mul(to_xyz(), rgb); }

Rgb blackbody_linear_srgb(double T, BlackbodyNorm norm) {
  Rgb c = xyz_to_linear_srgb(blackbody_xyz(T, norm));
  for (double& v : c) v = std::max(v, 0.0);
  return c;
}

double blackbody_warp(double T) { return kBlackbodyWarpA / T - kBlackbodyWarpB * std::log(T); }

BlackbodyTable make_blackbody_table(double T_lo, double T_hi, BlackbodyNorm norm, int entries) {
  BlackbodyTable t;
  t.entries = std::max(entries, 2);
  T_lo = std::max(T_lo, kBlackbodyTableFloor);
  T_hi = std::max(T_hi, T_lo * 1.001);
  const double s0 = blackbody_warp(T_hi), s1 = blackbody_warp(T_lo);
  t.warp_first = s0;
  t.entries_per_warp = (t.entries - 1) / (s1 - s0);
  t.rgbn.resize(size_t(t.entries) * 4);
  for (int i = 0; i < t.entries; ++i) {
    // the entry's temperature: warp is decreasing in T; bisection on log T
    const double target = s0 + i / t.entries_per_warp;
    double lo = std::log(T_lo), hi = std::log(T_hi);
    for (int k = 0; k < 100 && hi - lo > 1e-15 * std::abs(hi); ++k) {
      const double mid = 0.5 * (lo + hi);
      (blackbody_warp(std::exp(mid)) > target ? lo : hi) = mid;
    }
    const double T = i == 0 ? T_hi : i == t.entries - 1 ? T_lo : std::exp(0.5 * (lo + hi));
    double log_norm = 0;
    const Rgb xyz = blackbody_xyz(T, norm, &log_norm);
    Rgb c = xyz_to_linear_srgb(xyz);
    for (int k = 0; k < 3; ++k) {
      c[k] = std::max(c[k], 0.0);
      t.rgbn[size_t(i) * 4 + k] = float(c[k]);
      t.max_value = std::max(t.max_value, c[k]);
    }
    t.rgbn[size_t(i) * 4 + 3] = float(log_norm);
    t.spectrum_max = std::max(t.spectrum_max, spectrum_max_of(T, log_norm));
  }
  return t;
}

}  // namespace spectrack
