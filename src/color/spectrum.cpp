// spectrum.cpp: see spectrum.h.
#include "color/spectrum.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <mutex>
#include <stdexcept>
#include <thread>

namespace spectrack {

double cie_d65(double lambda_nm) {
  const double first = kCieD65[0].lambda_nm, last = kCieD65[kCieD65Samples - 1].lambda_nm;
  if (!(lambda_nm >= first && lambda_nm <= last)) return 0.0;
  const double f = (lambda_nm - first) / 5.0;
  const int i = std::min(static_cast<int>(f), kCieD65Samples - 2);
  const double t = f - i;
  return kCieD65[i].s * (1 - t) + kCieD65[i + 1].s * t;
}

double sigmoid(double x) {
  if (std::isinf(x)) return x > 0 ? 1.0 : 0.0;
  if (std::fabs(x) > 1e150) return x > 0 ? 1.0 : 0.0;  // 1 + x^2 would overflow; S is 1 or 0 to double precision
  // 1/2 + x / (2 r) with r = sqrt(1 + x^2) cancels for x << 0 (dark spectra, S ~ 1 / (4 x^2));
  // 1 + x / r = 1 / (r (r - x)) there keeps full relative precision
  const double r = std::sqrt(1.0 + x * x);
  return x < 0 ? 0.5 / (r * (r - x)) : 1.0 - 0.5 / (r * (r + x));
}

namespace {

double poly(const std::array<double, 3>& c, double u) { return (c[0] * u + c[1]) * u + c[2]; }

}  // namespace

double RgbSpectrum::operator()(double lambda_nm) const {
  const double u = (lambda_nm - kSpectrumLambdaMin) / (kSpectrumLambdaMax - kSpectrumLambdaMin);
  return scale * sigmoid(poly(c, u));
}

const std::vector<Rgb>& film_rgb_weights() {
  static const std::vector<Rgb> weights = [] {
    double norm = 0;  // sum of y-bar D65 over the 1 nm grid: D65 itself has Y = 1
    for (const CieSample& s : kCie1931) norm += s.y * cie_d65(s.lambda_nm);
    std::vector<Rgb> w;
    Rgb white{0, 0, 0};
    for (const CieSample& s : kCie1931) {
      w.push_back(xyz_to_linear_srgb({s.x / norm, s.y / norm, s.z / norm}));
      for (int k = 0; k < 3; ++k) white[k] += w.back()[k] * cie_d65(s.lambda_nm);
    }
    // White balance: the sRGB matrix is derived from D65's standard chromaticity (0.3127,
    // 0.3290); the tabulated D65 seen by the 1 nm observer sits 2e-5 away, so D65 itself would
    // come out as (1.00016, 0.99998, 0.99976). Scaling each channel by the inverse maps it to
    // (1, 1, 1) exactly, so a white reflectance under D65 is white and reachable by a spectrum <= 1.
    for (auto& v : w)
      for (int k = 0; k < 3; ++k) v[k] /= white[k];
    return w;
  }();
  return weights;
}

double film_emission_scale() {
  static const double k = [] {
    double y_d65 = 0;
    for (const CieSample& s : kCie1931) y_d65 += s.y * cie_d65(s.lambda_nm);
    return y_d65 / cie_y_integral();
  }();
  return k;
}

Rgb film_rgb_weight(double lambda_nm) {
  const std::vector<Rgb>& w = film_rgb_weights();
  if (!(lambda_nm >= kSpectrumLambdaMin && lambda_nm <= kSpectrumLambdaMax)) return {0, 0, 0};
  const double f = lambda_nm - kSpectrumLambdaMin;
  const int i = std::min(static_cast<int>(f), kCieSamples - 2);
  const double t = f - i;
  return {w[i][0] * (1 - t) + w[i + 1][0] * t, w[i][1] * (1 - t) + w[i + 1][1] * t,
          w[i][2] * (1 - t) + w[i + 1][2] * t};
}

// pbrt-v4's visible-wavelength importance density (Radziszewski et al. 2009's fit, as pbrt-v4
// SampleVisibleWavelengths / VisibleWavelengthsPdf): p(lambda) = 0.0039398042 /
// cosh^2(0.0072 (lambda - 538)) on [360, 830] nm, sampled by inverting its CDF in closed form.
double visible_wavelength_pdf(double lambda_nm) {
  if (!(lambda_nm >= kSpectrumLambdaMin && lambda_nm <= kSpectrumLambdaMax)) return 0.0;
  const double c = std::cosh(0.0072 * (lambda_nm - 538.0));
  return 0.0039398042 / (c * c);
}

double sample_visible_wavelength(double u) {
  return std::clamp(538.0 - 138.888889 * std::atanh(0.85691062 - 1.82750197 * u), kSpectrumLambdaMin,
                    kSpectrumLambdaMax);
}

std::array<double, 4> sample_wavelengths(double u) {
  std::array<double, 4> lambda;
  for (int i = 0; i < 4; ++i) {
    double ui = u + 0.25 * i;
    if (ui >= 1) ui -= 1;
    lambda[i] = sample_visible_wavelength(ui);
  }
  return lambda;
}

Rgb2SpecFit::Rgb2SpecFit() {
  const std::vector<Rgb>& film = film_rgb_weights();
  for (int i = 0; i < kCieSamples; ++i) {
    const double lambda = kCie1931[i].lambda_nm, d = cie_d65(lambda);
    u_.push_back((lambda - kSpectrumLambdaMin) / (kSpectrumLambdaMax - kSpectrumLambdaMin));
    w_.push_back({film[i][0] * d, film[i][1] * d, film[i][2] * d});
  }
}

Rgb Rgb2SpecFit::rgb_of(const RgbSpectrum& s) const {
  Rgb rgb{0, 0, 0};
  for (std::size_t i = 0; i < u_.size(); ++i) {
    const double v = s.scale * sigmoid(poly(s.c, u_[i]));
    for (int k = 0; k < 3; ++k) rgb[k] += v * w_[i][k];
  }
  return rgb;
}

double Rgb2SpecFit::fit(const Rgb& target, std::array<double, 3>& c, double tolerance, int max_iterations) const {
  // residual r = rgb(c) - target and its Jacobian J[k][j] = d rgb_k / d c_j, with
  // dS/dx = (1 + x^2)^(-3/2) / 2 and dx/dc = (u^2, u, 1)
  auto evaluate = [&](const std::array<double, 3>& cc, Rgb& r, double (*J)[3]) {
    r = {-target[0], -target[1], -target[2]};
    if (J)
      for (int k = 0; k < 3; ++k) J[k][0] = J[k][1] = J[k][2] = 0;
    for (std::size_t i = 0; i < u_.size(); ++i) {
      const double u = u_[i], x = poly(cc, u);
      const double v = sigmoid(x);
      for (int k = 0; k < 3; ++k) r[k] += v * w_[i][k];
      if (J) {
        const double q = 1.0 / std::sqrt(1.0 + x * x);
        const double dv = std::isfinite(x) ? 0.5 * q * q * q : 0.0;
        const double du[3] = {u * u, u, 1.0};
        for (int k = 0; k < 3; ++k)
          for (int j = 0; j < 3; ++j) J[k][j] += dv * du[j] * w_[i][k];
      }
    }
    return std::max({std::fabs(r[0]), std::fabs(r[1]), std::fabs(r[2])});
  };
  Rgb r;
  double J[3][3];
  double err = evaluate(c, r, J);
  double mu = 1e-3;
  for (int it = 0; it < max_iterations && err > tolerance; ++it) {
    // (J^T J + mu diag(J^T J)) delta = -J^T r
    double A[3][3], b[3];
    for (int i = 0; i < 3; ++i) {
      b[i] = 0;
      for (int k = 0; k < 3; ++k) b[i] -= J[k][i] * r[k];
      for (int j = 0; j < 3; ++j) {
        A[i][j] = 0;
        for (int k = 0; k < 3; ++k) A[i][j] += J[k][i] * J[k][j];
      }
    }
    bool improved = false;
    for (int tries = 0; tries < 30 && !improved; ++tries) {
      double M[3][3];
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) M[i][j] = A[i][j] + (i == j ? mu * std::max(A[i][i], 1e-30) : 0.0);
      // Cramer's rule on the 3x3 system
      const double det = M[0][0] * (M[1][1] * M[2][2] - M[1][2] * M[2][1]) -
                         M[0][1] * (M[1][0] * M[2][2] - M[1][2] * M[2][0]) +
                         M[0][2] * (M[1][0] * M[2][1] - M[1][1] * M[2][0]);
      if (!(std::fabs(det) > 0) || !std::isfinite(det)) {
        mu *= 10;
        continue;
      }
      std::array<double, 3> delta;
      for (int j = 0; j < 3; ++j) {
        double Mj[3][3];
        std::memcpy(Mj, M, sizeof M);
        for (int i = 0; i < 3; ++i) Mj[i][j] = b[i];
        delta[j] = (Mj[0][0] * (Mj[1][1] * Mj[2][2] - Mj[1][2] * Mj[2][1]) -
                    Mj[0][1] * (Mj[1][0] * Mj[2][2] - Mj[1][2] * Mj[2][0]) +
                    Mj[0][2] * (Mj[1][0] * Mj[2][1] - Mj[1][1] * Mj[2][0])) / det;
      }
      std::array<double, 3> c2{c[0] + delta[0], c[1] + delta[1], c[2] + delta[2]};
      Rgb r2;
      const double e2 = evaluate(c2, r2, nullptr);
      const double n2 = r2[0] * r2[0] + r2[1] * r2[1] + r2[2] * r2[2];
      const double n1 = r[0] * r[0] + r[1] * r[1] + r[2] * r[2];
      if (std::isfinite(e2) && n2 < n1) {
        c = c2;
        err = evaluate(c, r, J);
        mu = std::max(mu * 0.3, 1e-12);
        improved = true;
      } else {
        mu *= 10;
      }
    }
    if (!improved) break;
  }
  return err;
}

namespace {

double smoothstep(double x) { return x * x * (3.0 - 2.0 * x); }

// the colour of table entry (l, zi, yi, xi)
Rgb table_colour(const Rgb2SpecTable& t, int l, int zi, int yi, int xi) {
  const double z = t.z[zi], x = xi / double(t.res - 1), y = yi / double(t.res - 1);
  Rgb rgb;
  rgb[l] = z;
  rgb[(l + 1) % 3] = x * z;
  rgb[(l + 2) % 3] = y * z;
  return rgb;
}

std::array<double, 3> gray_coeffs(double v) {
  v = std::clamp(v, 1e-9, 1.0 - 1e-9);  // S(c2) = v exactly: c2 = (v - 1/2) / sqrt(v (1 - v))
  return {0.0, 0.0, (v - 0.5) / std::sqrt(v * (1.0 - v))};
}

// Fits `to` starting from coefficients c that fit `from`, along the straight line between the
// two colours in steps that halve where a step does not converge (continuation).
double fit_along(const Rgb2SpecFit& f, const Rgb& from, const Rgb& to, std::array<double, 3>& c) {
  constexpr double kTol = 1e-7;
  double t = 0, dt = 1;
  double err = 0;
  while (t < 1) {
    const double t2 = std::min(1.0, t + dt);
    const Rgb target{from[0] + (to[0] - from[0]) * t2, from[1] + (to[1] - from[1]) * t2,
                     from[2] + (to[2] - from[2]) * t2};
    std::array<double, 3> c2 = c;
    err = f.fit(target, c2, kTol, t2 < 1 ? 50 : 200);
    if (err <= kTol || (t2 < 1 && err <= 1e-4)) {
      c = c2;
      t = t2;
      dt = std::min(1.0, dt * 2);
    } else if (dt > 1.0 / 4096) {
      dt *= 0.5;
    } else {
      return err;  // no progress: the caller reports the colour
    }
  }
  return err;
}

}  // namespace

Rgb2SpecTable make_rgb2spec_table(int res, int threads) {
  if (res < 3 || res > 256) throw std::runtime_error("rgb2spec table: res must be in [3, 256]");
  Rgb2SpecTable t;
  t.res = res;
  for (int i = 0; i < res; ++i) t.z.push_back(static_cast<float>(smoothstep(smoothstep(i / double(res - 1)))));
  t.coeffs.assign(static_cast<std::size_t>(9) * res * res * res, 0.0f);
  const Rgb2SpecFit f;
  auto at = [&](int l, int zi, int yi, int xi) {
    return &t.coeffs[((((static_cast<std::size_t>(l) * res + zi) * res + yi) * res + xi)) * 3];
  };
  // One column (l, xi, yi) per task: solve at z level k0 (a dark level, where the spectra are
  // gentle) by continuation from the gray of the same z, then walk up and down in z, each level
  // starting from its neighbour's coefficients. Level 0 (black) keeps level 1's coefficients:
  // lookups never read it (spectrum.h).
  const int k0 = std::max(1, res / 5);
  std::atomic<int> next{0};
  std::mutex mutex;
  std::string failure;
  double worst = 0;
  auto worker = [&] {
    double local_worst = 0;
    for (;;) {
      const int task = next.fetch_add(1);
      if (task >= 3 * res * res) break;
      const int l = task / (res * res), yi = (task / res) % res, xi = task % res;
      auto solve = [&](int zi, const Rgb& from, std::array<double, 3>& c) {
        const Rgb target = table_colour(t, l, zi, yi, xi);
        const double err = fit_along(f, from, target, c);
        if (!(err <= 1e-6)) {
          std::lock_guard<std::mutex> lock(mutex);
          if (failure.empty())
            failure = "rgb2spec table: no fit for (" + std::to_string(target[0]) + ", " + std::to_string(target[1]) +
                      ", " + std::to_string(target[2]) + "): residual " + std::to_string(err);
        }
        local_worst = std::max(local_worst, err);
        for (int k = 0; k < 3; ++k) at(l, zi, yi, xi)[k] = static_cast<float>(c[k]);
        return target;
      };
      std::array<double, 3> c0 = gray_coeffs(t.z[k0]);
      const double z0 = t.z[k0];
      Rgb prev = solve(k0, Rgb{z0, z0, z0}, c0);
      std::array<double, 3> c = c0;
      for (int zi = k0 + 1; zi < res; ++zi) prev = solve(zi, prev, c);
      c = c0;
      prev = table_colour(t, l, k0, yi, xi);
      for (int zi = k0 - 1; zi >= 1; --zi) prev = solve(zi, prev, c);
      for (int k = 0; k < 3; ++k) at(l, 0, yi, xi)[k] = at(l, 1, yi, xi)[k];
    }
    std::lock_guard<std::mutex> lock(mutex);
    worst = std::max(worst, local_worst);
  };
  std::vector<std::thread> pool;
  for (int i = 1; i < std::max(1, threads); ++i) pool.emplace_back(worker);
  worker();
  for (auto& th : pool) th.join();
  if (!failure.empty()) throw std::runtime_error(failure);
  t.max_residual = worst;
  return t;
}

#if !defined(__BYTE_ORDER__) || __BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__
#error "the rgb2spec table file is little endian: add byte swapping for this target"
#endif

namespace {
constexpr char kMagic[] = "spectrack-rgb2spec 1\n";
constexpr std::size_t kMagicSize = sizeof kMagic - 1;
}  // namespace

std::vector<char> serialize_rgb2spec_table(const Rgb2SpecTable& t) {
  std::vector<char> out;
  out.reserve(kMagicSize + 8 + 4 * (t.z.size() + t.coeffs.size()));
  auto put = [&](const void* p, std::size_t n) {
    out.insert(out.end(), static_cast<const char*>(p), static_cast<const char*>(p) + n);
  };
  const std::int32_t res = t.res;
  const float residual = static_cast<float>(t.max_residual);
  put(kMagic, kMagicSize);
  put(&res, 4);
  put(&residual, 4);
  put(t.z.data(), t.z.size() * 4);
  put(t.coeffs.data(), t.coeffs.size() * 4);
  return out;
}

bool parse_rgb2spec_table(const void* bytes, std::size_t size, Rgb2SpecTable& t, std::string* error) {
  auto fail = [&](const std::string& why) {
    if (error) *error = "rgb2spec table: " + why;
    return false;
  };
  const char* p = static_cast<const char*>(bytes);
  if (size < kMagicSize + 8 || std::memcmp(p, kMagic, kMagicSize) != 0) return fail("not a spectrack-rgb2spec 1 table");
  std::int32_t res;
  float residual;
  std::memcpy(&res, p + kMagicSize, 4);
  std::memcpy(&residual, p + kMagicSize + 4, 4);
  if (res < 3 || res > 256) return fail("res " + std::to_string(res) + " outside [3, 256]");
  const std::size_t n_coeffs = static_cast<std::size_t>(9) * res * res * res;
  if (size != kMagicSize + 8 + 4 * (res + n_coeffs))
    return fail(std::to_string(size) + " bytes, expected " + std::to_string(kMagicSize + 8 + 4 * (res + n_coeffs)) +
                " for res " + std::to_string(res));
  t.res = res;
  t.max_residual = residual;
  t.z.resize(res);
  t.coeffs.resize(n_coeffs);
  std::memcpy(t.z.data(), p + kMagicSize + 8, 4 * res);
  std::memcpy(t.coeffs.data(), p + kMagicSize + 8 + 4 * res, 4 * n_coeffs);
  if (t.z.front() != 0.0f || t.z.back() != 1.0f) return fail("z levels do not span [0, 1]");
  for (int i = 1; i < res; ++i)
    if (!(t.z[i] > t.z[i - 1])) return fail("z levels not increasing at level " + std::to_string(i));
  for (float v : t.coeffs)
    if (!std::isfinite(v)) return fail("a coefficient is not finite");
  return true;
}

RgbSpectrum rgb2spec(const Rgb2SpecTable& t, const Rgb& in) {
  Rgb rgb;
  for (int k = 0; k < 3; ++k) rgb[k] = std::clamp(std::isnan(in[k]) ? 0.0 : in[k], 0.0, 1.0);
  RgbSpectrum s;
  if (rgb[0] == rgb[1] && rgb[1] == rgb[2]) {  // flat: S(0) = 1/2
    s.c = {0, 0, 0};
    s.scale = 2 * rgb[0];
    return s;
  }
  const int l = rgb[0] >= rgb[1] ? (rgb[0] >= rgb[2] ? 0 : 2) : (rgb[1] >= rgb[2] ? 1 : 2);
  double z = rgb[l];
  const double x = rgb[(l + 1) % 3] / z, y = rgb[(l + 2) % 3] / z;
  const int res = t.res;
  if (z < t.z[1]) {  // darker than the first level: that level's spectrum, scaled
    s.scale = z / t.z[1];
    z = t.z[1];
  }
  const int zi = std::clamp(static_cast<int>(std::upper_bound(t.z.begin(), t.z.end(), static_cast<float>(z)) - t.z.begin()) - 1,
                            1, res - 2);
  const double tz = std::clamp((z - t.z[zi]) / (t.z[zi + 1] - t.z[zi]), 0.0, 1.0);
  const double xf = x * (res - 1), yf = y * (res - 1);
  const int xi = std::min(static_cast<int>(xf), res - 2), yi = std::min(static_cast<int>(yf), res - 2);
  const double tx = xf - xi, ty = yf - yi;
  for (int k = 0; k < 3; ++k) {
    double v = 0;
    for (int dz = 0; dz < 2; ++dz)
      for (int dy = 0; dy < 2; ++dy)
        for (int dx = 0; dx < 2; ++dx) {
          const double w = (dz ? tz : 1 - tz) * (dy ? ty : 1 - ty) * (dx ? tx : 1 - tx);
          const std::size_t i = ((((static_cast<std::size_t>(l) * res + zi + dz) * res + yi + dy) * res + xi + dx)) * 3;
          v += w * t.coeffs[i + k];
        }
    s.c[k] = v;
  }
  return s;
}

RgbSpectrum rgb2spec_fitted(const Rgb2SpecFit& f, const Rgb2SpecTable& t, const Rgb& rgb) {
  RgbSpectrum s = rgb2spec(t, rgb);
  if (s.scale == 0 || (s.c[0] == 0 && s.c[1] == 0 && s.c[2] == 0)) return s;  // black or flat: exact
  Rgb target;
  for (int k = 0; k < 3; ++k) target[k] = std::clamp(std::isnan(rgb[k]) ? 0.0 : rgb[k], 0.0, 1.0) / s.scale;
  std::array<double, 3> c = s.c;
  const RgbSpectrum from{s.c, 1.0};
  if (f.fit(target, c) > 1e-7) {
    c = s.c;
    fit_along(f, f.rgb_of(from), target, c);
  }
  // keep whichever is closer: the refined fit, or the table's own coefficients if the fit failed
  auto error = [&](const std::array<double, 3>& cc) {
    const Rgb b = f.rgb_of(RgbSpectrum{cc, 1.0});
    return std::max({std::fabs(b[0] - target[0]), std::fabs(b[1] - target[1]), std::fabs(b[2] - target[2])});
  };
  if (error(c) < error(s.c)) s.c = c;
  return s;
}

namespace {

// rgb / (2 max(rgb)) through `upsample`, scaled back by 2 max(rgb) (pbrt-v4's RGBUnboundedSpectrum)
template <class Upsample>
RgbSpectrum unbounded(const Rgb& rgb, const char* name, Upsample upsample) {
  for (double v : rgb)
    if (!std::isfinite(v) || !std::isfinite(2 * v))
      throw std::domain_error(std::string(name) + ": a component is not finite or above half the largest double");
  const double m = std::max({rgb[0], rgb[1], rgb[2]});
  if (!(m > 0)) return RgbSpectrum{{0, 0, 0}, 0};
  const double scale = 2 * m;
  RgbSpectrum s = upsample(Rgb{rgb[0] / scale, rgb[1] / scale, rgb[2] / scale});
  s.scale *= scale;
  return s;
}

}  // namespace

RgbSpectrum rgb2spec_unbounded(const Rgb2SpecFit& f, const Rgb2SpecTable& t, const Rgb& rgb) {
  return unbounded(rgb, "rgb2spec_unbounded", [&](const Rgb& c) { return rgb2spec_fitted(f, t, c); });
}

RgbSpectrum rgb2spec_unbounded_lookup(const Rgb2SpecTable& t, const Rgb& rgb) {
  // the largest component is exactly 1/2 (never below the table's first level) and a gray is flat
  // with scale 2 x 1/2: the lookup's scale is 1, so the result's is 2 max(rgb)
  return unbounded(rgb, "rgb2spec_unbounded_lookup", [&](const Rgb& c) { return rgb2spec(t, c); });
}

}  // namespace spectrack
