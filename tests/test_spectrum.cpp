// test_spectrum.cpp: spectral mode's colour side (src/color/spectrum.h, kernels/spectrum.h): the
// CIE D65 data, the Jakob-Hanika fitter, the build-time table and its lookups, the table file's
// checks, wavelength sampling and the spectral film's weights, and the device functions against
// the host's (suite SpectrumDevice, which needs an OpenCL device; the rest is host-only).
//
// Design: every check integrates spectra back to linear sRGB with the fitter's own weights (CIE
// 1931 observer x D65 on the 1 nm grid), so a round trip measures the upsampling alone. Scene
// constants go through rgb2spec_fitted (the table's coefficients refined by the fitter) and must
// round-trip to the fit's tolerance; the table alone (what a kernel would read) is held to the
// accuracy measured for it at res 64, per region of the cube.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <cstdint>
#include <cstring>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "color/spectrum.h"
#include "device/probe.h"
#include "test_util.h"

namespace spectrack {
namespace {

double max_abs_diff(const Rgb& a, const Rgb& b) {
  return std::max({std::fabs(a[0] - b[0]), std::fabs(a[1] - b[1]), std::fabs(a[2] - b[2])});
}

const Rgb2SpecFit& fitter() {
  static const Rgb2SpecFit f;
  return f;
}

TEST(Spectrum, D65TableIsTheCieIlluminant) {
  EXPECT_EQ(kCieD65[0].lambda_nm, 300);
  EXPECT_EQ(kCieD65[kCieD65Samples - 1].lambda_nm, 830);
  EXPECT_DOUBLE_EQ(cie_d65(560), 100.0);
  EXPECT_DOUBLE_EQ(cie_d65(562.5), 0.5 * (100.0 + 98.1671));  // linear between samples
  EXPECT_EQ(cie_d65(299), 0.0);
  EXPECT_EQ(cie_d65(831), 0.0);
  // its chromaticity through the 1 nm observer: D65's (0.31272, 0.32903) (CIE 015:2018 table T.3)
  double X = 0, Y = 0, Z = 0;
  for (const CieSample& s : kCie1931) {
    X += s.x * cie_d65(s.lambda_nm);
    Y += s.y * cie_d65(s.lambda_nm);
    Z += s.z * cie_d65(s.lambda_nm);
  }
  EXPECT_NEAR(X / (X + Y + Z), 0.31272, 2e-5);
  EXPECT_NEAR(Y / (X + Y + Z), 0.32903, 2e-5);
}

TEST(Spectrum, SigmoidModel) {
  EXPECT_DOUBLE_EQ(sigmoid(0), 0.5);
  EXPECT_DOUBLE_EQ(sigmoid(INFINITY), 1.0);
  EXPECT_DOUBLE_EQ(sigmoid(-INFINITY), 0.0);
  EXPECT_DOUBLE_EQ(sigmoid(1e300), 1.0);
  EXPECT_NEAR(sigmoid(1.0), 0.5 + 0.5 / std::sqrt(2.0), 1e-15);
  EXPECT_NEAR(sigmoid(-3.0) + sigmoid(3.0), 1.0, 1e-15);
  // u = 0 at 360 nm, 1 at 830 nm
  const RgbSpectrum s{{2.0, -3.0, 0.5}, 0.8};
  EXPECT_NEAR(s(360), 0.8 * sigmoid(0.5), 1e-15);
  EXPECT_NEAR(s(830), 0.8 * sigmoid(2.0 - 3.0 + 0.5), 1e-15);
  EXPECT_NEAR(s(595), 0.8 * sigmoid(2.0 * 0.25 - 3.0 * 0.5 + 0.5), 1e-15);
}

TEST(Spectrum, WhiteAndGraysAreFlat) {
  const Rgb2SpecTable& t = rgb2spec_srgb();
  for (double v : {1.0, 0.5, 0.18, 1e-4}) {
    const RgbSpectrum s = rgb2spec(t, {v, v, v});
    for (double lambda = 360; lambda <= 830; lambda += 10) EXPECT_DOUBLE_EQ(s(lambda), v) << "gray " << v;
    const Rgb back = fitter().rgb_of(s);
    EXPECT_LT(max_abs_diff(back, {v, v, v}), 1e-12 * std::max(v, 1.0)) << "gray " << v;
  }
  const RgbSpectrum black = rgb2spec(t, {0, 0, 0});
  EXPECT_EQ(black(500), 0.0);
  EXPECT_EQ(rgb2spec_unbounded(fitter(), t, {0, 0, 0})(500), 0.0);
}

// The criterion: every colour of a grid over [0, 1]^3 upsampled and integrated back
// within 1e-3. Scene constants (rgb2spec_fitted) do far better: the fit's own tolerance.
TEST(Spectrum, FittedRoundTripOnAGridOfColours) {
  const Rgb2SpecTable& t = rgb2spec_srgb();
  const int n = 11;
  double worst = 0;
  Rgb worst_colour{};
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j)
      for (int k = 0; k < n; ++k) {
        const Rgb c{i / (n - 1.0), j / (n - 1.0), k / (n - 1.0)};
        const RgbSpectrum s = rgb2spec_fitted(fitter(), t, c);
        const double e = max_abs_diff(fitter().rgb_of(s), c);
        if (e > worst) worst = e, worst_colour = c;
      }
  std::printf("fitted round trip on the %d^3 grid: worst %.2e\n", n, worst);
  EXPECT_LT(worst, 1e-6) << "worst colour (" << worst_colour[0] << ", " << worst_colour[1] << ", " << worst_colour[2]
                         << ")";
}

// The table alone (a kernel's lookup) against the accuracy measured for it at res 64: the
// coefficients are interpolated, and near the cube's top the spectra saturate towards 1, where
// the coefficients grow fast (spectrum.h).
TEST(Spectrum, TableRoundTripAccuracy) {
  const Rgb2SpecTable& t = rgb2spec_srgb();
  const int n = 21;
  double worst_low = 0, worst_high = 0;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j)
      for (int k = 0; k < n; ++k) {
        const Rgb c{i / (n - 1.0), j / (n - 1.0), k / (n - 1.0)};
        const double e = max_abs_diff(fitter().rgb_of(rgb2spec(t, c)), c);
        (std::max({c[0], c[1], c[2]}) <= 0.8 ? worst_low : worst_high) = std::max(
            e, std::max({c[0], c[1], c[2]}) <= 0.8 ? worst_low : worst_high);
      }
  std::printf("table round trip on the %d^3 grid: max component <= 0.8: %.2e, above: %.2e\n", n, worst_low,
              worst_high);
  EXPECT_LT(worst_low, 1e-3);
  EXPECT_LT(worst_high, 2e-3);
  // random colours per band of the largest component, against bench/RESULTS.md "RGB upsampling"
  // (100000 colours: 7.1e-4, 1.3e-3, 1.7e-3, 1.9e-3, 5.5e-3) with a margin of 1.5x for another
  // sample of colours; a table fitted or interpolated wrongly is off by far more
  const double edges[6] = {0, 0.5, 0.8, 0.9, 0.97, 1.0};
  const double limit[5] = {1.1e-3, 2.0e-3, 2.6e-3, 2.9e-3, 8.2e-3};
  double worst_band[5] = {0, 0, 0, 0, 0};
  std::mt19937_64 engine(11);
  for (int i = 0; i < 20000; ++i) {
    const Rgb c{(engine() >> 11) * 0x1.0p-53, (engine() >> 11) * 0x1.0p-53, (engine() >> 11) * 0x1.0p-53};
    const double m = std::max({c[0], c[1], c[2]});
    int b = 0;
    while (b < 4 && m >= edges[b + 1]) ++b;
    worst_band[b] = std::max(worst_band[b], max_abs_diff(fitter().rgb_of(rgb2spec(t, c)), c));
  }
  for (int b = 0; b < 5; ++b) {
    std::printf("table round trip, largest component in [%.2f, %.2f): worst %.2e\n", edges[b], edges[b + 1],
                worst_band[b]);
    EXPECT_LT(worst_band[b], limit[b]) << "band " << b;
  }
  // at the table's own nodes the fit is exact (no interpolation)
  const int res = t.res;
  for (int l = 0; l < 3; ++l)
    for (int zi : {1, res / 5, res / 2, res - 2, res - 1})
      for (int yi : {0, res / 3, res - 1})
        for (int xi : {0, res / 2, res - 2}) {
          const float* c = &t.coeffs[((((static_cast<std::size_t>(l) * res + zi) * res + yi) * res + xi)) * 3];
          Rgb colour;
          colour[l] = t.z[zi];
          colour[(l + 1) % 3] = t.z[zi] * (xi / double(res - 1));
          colour[(l + 2) % 3] = t.z[zi] * (yi / double(res - 1));
          const Rgb back = fitter().rgb_of(RgbSpectrum{{c[0], c[1], c[2]}, 1.0});
          EXPECT_LT(max_abs_diff(back, colour), 2e-6) << "node " << l << " " << zi << " " << yi << " " << xi;
        }
}

TEST(Spectrum, UnboundedColoursKeepTheirScale) {
  const Rgb2SpecTable& t = rgb2spec_srgb();
  for (const Rgb c : {Rgb{3.0, 1.5, 0.2}, Rgb{0.02, 0.5, 40.0}, Rgb{1e-3, 1e-3, 2e-3}, Rgb{7, 7, 7}}) {
    const RgbSpectrum s = rgb2spec_unbounded(fitter(), t, c);
    const double m = std::max({c[0], c[1], c[2]});
    EXPECT_NEAR(s.scale, 2 * m, 1e-12 * m);
    EXPECT_LT(max_abs_diff(fitter().rgb_of(s), c), 1e-6 * m);
  }
  EXPECT_THROW(rgb2spec_unbounded(fitter(), t, {INFINITY, 1, 1}), std::domain_error);
  EXPECT_THROW(rgb2spec_unbounded(fitter(), t, {NAN, 1, 1}), std::domain_error);
  EXPECT_THROW(rgb2spec_unbounded(fitter(), t, {1e308, 1, 1}), std::domain_error);
}

TEST(Spectrum, DarkColoursScaleTheFirstLevel) {
  // below the first z level the spectrum is that level's, scaled: RGB is linear in the spectrum
  const Rgb2SpecTable& t = rgb2spec_srgb();
  const Rgb c{t.z[1] * 0.5, t.z[1] * 0.1, t.z[1] * 0.3};
  const RgbSpectrum s = rgb2spec(t, c);
  EXPECT_NEAR(s.scale, 0.5, 1e-6);
  // exact in brightness: the spectrum is level 1's, halved
  const RgbSpectrum level1 = rgb2spec(t, {c[0] / s.scale, c[1] / s.scale, c[2] / s.scale});
  for (double lambda : {400.0, 550.0, 700.0}) EXPECT_NEAR(s(lambda), 0.5 * level1(lambda), 1e-12);
  const double e = max_abs_diff(fitter().rgb_of(rgb2spec_fitted(fitter(), t, c)), c);
  EXPECT_LT(e, 1e-7 * 0.5 + 1e-12);  // the fit's absolute tolerance, scaled (spectrum.h)
}

TEST(Spectrum, GeneratorAndTableFile) {
  // a small table through the same generator the build runs, then its file format
  const Rgb2SpecTable t = make_rgb2spec_table(6, 2);
  EXPECT_EQ(t.res, 6);
  EXPECT_LE(t.max_residual, 1e-6);
  EXPECT_EQ(t.z.front(), 0.0f);
  EXPECT_EQ(t.z.back(), 1.0f);
  const std::vector<char> bytes = serialize_rgb2spec_table(t);
  Rgb2SpecTable back;
  std::string error;
  ASSERT_TRUE(parse_rgb2spec_table(bytes.data(), bytes.size(), back, &error)) << error;
  EXPECT_EQ(back.res, t.res);
  EXPECT_EQ(back.z, t.z);
  EXPECT_EQ(back.coeffs, t.coeffs);

  auto refused = [&](std::vector<char> b, const std::string& why) {
    Rgb2SpecTable x;
    std::string e;
    EXPECT_FALSE(parse_rgb2spec_table(b.data(), b.size(), x, &e)) << why;
    EXPECT_NE(e.find(why), std::string::npos) << e;
  };
  refused(std::vector<char>(bytes.begin(), bytes.end() - 4), "bytes, expected");
  refused(std::vector<char>(bytes.begin(), bytes.begin() + 10), "not a spectrack-rgb2spec 1 table");
  std::vector<char> b = bytes;
  b[0] = 'X';
  refused(b, "not a spectrack-rgb2spec 1 table");
  const std::size_t header = std::strlen("spectrack-rgb2spec 1\n");
  b = bytes;
  const std::int32_t huge = 1000;
  std::memcpy(b.data() + header, &huge, 4);
  refused(b, "outside [3, 256]");
  b = bytes;
  const float nan = NAN;
  std::memcpy(b.data() + b.size() - 4, &nan, 4);
  refused(b, "not finite");
  b = bytes;
  const float z = 0.9f;  // level 2 below level 1
  std::memcpy(b.data() + header + 8 + 4 * 2, &z, 4);
  std::memcpy(b.data() + header + 8 + 4 * 1, &z, 4);
  refused(b, "not increasing");
  EXPECT_THROW(make_rgb2spec_table(2, 1), std::runtime_error);
}

TEST(Spectrum, EmbeddedTableIsTheBuildsFit) {
  const Rgb2SpecTable& t = rgb2spec_srgb();
  EXPECT_EQ(t.res, 64);
  EXPECT_LE(t.max_residual, 1e-6);
  EXPECT_EQ(t.coeffs.size(), static_cast<std::size_t>(9) * 64 * 64 * 64);
}

// uniforms in [0, 1) from a fixed-seed engine (its bits, not a library distribution: reproducible everywhere)
struct Uniforms {
  std::mt19937_64 engine{20261203};
  double operator()() { return (engine() >> 11) * 0x1.0p-53; }
};

TEST(Spectrum, VisibleWavelengthSampling) {
  // the density integrates to 1 over [360, 830] nm and sample_visible_wavelength inverts its CDF
  double cdf = 0;
  const double h = 0.01;
  std::vector<std::pair<double, double>> cdf_at;  // (lambda, CDF)
  for (double lambda = 360; lambda < 830 - h / 2; lambda += h) {
    cdf += h * (visible_wavelength_pdf(lambda) + 4 * visible_wavelength_pdf(lambda + h / 2) +
                visible_wavelength_pdf(lambda + h)) / 6;
    cdf_at.push_back({lambda + h, cdf});
  }
  EXPECT_NEAR(cdf, 1.0, 2e-4);  // pbrt-v4's constants are rounded to 8 digits
  for (double u : {0.001, 0.1, 0.25, 0.5, 0.75, 0.9, 0.999}) {
    const double lambda = sample_visible_wavelength(u);
    auto it = std::lower_bound(cdf_at.begin(), cdf_at.end(), std::make_pair(lambda, 0.0));
    ASSERT_NE(it, cdf_at.end());
    EXPECT_NEAR(it->second, u, 3e-4) << "u " << u << " lambda " << lambda;
  }
  EXPECT_NEAR(sample_visible_wavelength(0), 360, 0.5);
  EXPECT_NEAR(sample_visible_wavelength(1), 830, 0.5);
  EXPECT_EQ(visible_wavelength_pdf(359), 0.0);
  EXPECT_EQ(visible_wavelength_pdf(831), 0.0);
  // the four wavelengths of a path: u, u + 1/4, u + 1/2, u + 3/4, wrapped
  const auto l = sample_wavelengths(0.8);
  EXPECT_DOUBLE_EQ(l[0], sample_visible_wavelength(0.8));
  EXPECT_DOUBLE_EQ(l[1], sample_visible_wavelength(0.05));
  EXPECT_DOUBLE_EQ(l[2], sample_visible_wavelength(0.3));
  EXPECT_DOUBLE_EQ(l[3], sample_visible_wavelength(0.55));
}

// The spectral film's estimator, (1/4) sum_i L(lambda_i) F(lambda_i) / p(lambda_i), has the
// expectation of the 1 nm sums the fitter uses: D65 gives white, a reflectance under D65 its colour.
TEST(Spectrum, SpectralFilmEstimatesTheColour) {
  const Rgb2SpecTable& t = rgb2spec_srgb();
  const RgbSpectrum red = rgb2spec_fitted(fitter(), t, {0.7, 0.2, 0.1});
  struct Case {
    const char* name;
    std::function<double(double)> L;
    Rgb expect;
  };
  const Case cases[] = {{"D65", [](double l) { return cie_d65(l); }, {1, 1, 1}},
                        {"red reflectance under D65", [&](double l) { return red(l) * cie_d65(l); }, {0.7, 0.2, 0.1}}};
  for (const Case& c : cases) {
    Uniforms u;
    const int n = 20000;
    double sum[3] = {0, 0, 0}, sum2[3] = {0, 0, 0};
    for (int i = 0; i < n; ++i) {
      const auto lambda = sample_wavelengths(u());
      Rgb est{0, 0, 0};
      for (double l : lambda) {
        const Rgb F = film_rgb_weight(l);
        for (int k = 0; k < 3; ++k) est[k] += 0.25 * c.L(l) * F[k] / visible_wavelength_pdf(l);
      }
      for (int k = 0; k < 3; ++k) sum[k] += est[k], sum2[k] += est[k] * est[k];
    }
    for (int k = 0; k < 3; ++k) {
      const double mean = sum[k] / n, se = std::sqrt((sum2[k] / n - mean * mean) / (n - 1));
      EXPECT_LT(std::fabs(mean - c.expect[k]), 4 * se + 2e-4) << c.name << " channel " << k << " mean " << mean
                                                                << " se " << se;
      EXPECT_LT(se, 0.02 * std::max(c.expect[k], 0.1)) << c.name;  // the estimator is a useful one
    }
  }
}

TEST(SpectrumDevice, DeviceFunctionsMatchTheHost) {
  using namespace st_test;
  const std::string dir = temp_dir("spectrum_device");
  const nlohmann::json scene = {{"format", "spectrack-scene/1"},
                                {"camera", {{"type", "orthographic"}, {"position", {0, 0, -3}}, {"look_at", {0, 0, 0}},
                                            {"up", {0, 1, 0}}, {"height", 1.0}}},
                                {"film", {{"width", 4}, {"height", 4}, {"spp", 1}}},
                                {"lights", nlohmann::json::array()},
                                {"media", nlohmann::json::array()}};
  Renderer r(scene_from_json(scene, dir), quiet_options());
  Probe probe(r);
  const Rgb2SpecTable& t = rgb2spec_srgb();
  Uniforms u;
  std::vector<std::array<float, 4>> in;
  // grays, black, white, dark colours below the first level, saturated and near-white ones, random
  for (const Rgb c : {Rgb{0, 0, 0}, Rgb{1, 1, 1}, Rgb{0.18, 0.18, 0.18}, Rgb{1, 0, 0}, Rgb{0, 1, 0}, Rgb{0, 0, 1},
                      Rgb{1, 1, 0}, Rgb{0.99, 0.98, 0.95}, Rgb{t.z[1] * 0.5, t.z[1] * 0.1, t.z[1] * 0.3},
                      Rgb{0.3, 0.6, 0.6}})
    in.push_back({float(c[0]), float(c[1]), float(c[2]), float(u())});
  const size_t dark_item = 8;  // below the first z level: the device's scaled branch
  for (int i = 0; i < 4000; ++i) in.push_back({float(u()), float(u()), float(u()), float(u())});
  const auto out = probe.spectrum(in);
  ASSERT_EQ(out.size(), in.size());
  EXPECT_NEAR(out[dark_item].coeffs[3], 0.5, 1e-5);
  double film_sum[3] = {0, 0, 0}, film_sum2[3] = {0, 0, 0}, expect_sum[3] = {0, 0, 0};
  const int first_random = 10;
  for (size_t i = 0; i < in.size(); ++i) {
    const Rgb c{in[i][0], in[i][1], in[i][2]};
    const RgbSpectrum h = rgb2spec(t, c);
    const auto& d = out[i];
    for (int k = 0; k < 3; ++k)
      // float interpolation of neighbours up to ~100 in size (near white) against the host's double
      ASSERT_NEAR(d.coeffs[k], h.c[k], 1e-4 * std::max(1.0, std::fabs(h.c[k]))) << "item " << i << " coefficient " << k;
    ASSERT_NEAR(d.coeffs[3], h.scale, 1e-6 * std::max(1.0, h.scale)) << "item " << i;
    const auto lambda = sample_wavelengths(in[i][3]);
    Rgb film{0, 0, 0};
    for (int k = 0; k < 4; ++k) {
      ASSERT_NEAR(d.lambda[k], lambda[k], 2e-3) << "item " << i << " lane " << k;
      const double l = d.lambda[k];  // the rest at the device's wavelength
      ASSERT_NEAR(d.pdf[k], visible_wavelength_pdf(l), 1e-5 * visible_wavelength_pdf(l)) << "item " << i;
      const RgbSpectrum hd{{d.coeffs[0], d.coeffs[1], d.coeffs[2]}, d.coeffs[3]};
      ASSERT_NEAR(d.value[k], hd(l), 1e-5) << "item " << i << " lane " << k;
      ASSERT_NEAR(d.value[k], h(l), 1e-4) << "item " << i << " lane " << k << " (host coefficients)";
      const Rgb F = film_rgb_weight(l);
      for (int j = 0; j < 3; ++j) film[j] += 0.25 * d.value[k] * F[j] / d.pdf[k];
    }
    for (int j = 0; j < 3; ++j) ASSERT_NEAR(d.film_rgb[j], film[j], 1e-4 * std::max(1.0, std::fabs(film[j]))) << "item " << i;
    if (i >= size_t(first_random)) {
      // the film's expectation: the 1 nm sum of s(lambda) F(lambda)
      // (per item: estimate minus expectation, whose mean must be 0 within 4 SE)
      const std::vector<Rgb>& F = film_rgb_weights();
      for (int j = 0; j < 3; ++j) {
        double expect = 0;
        for (int s = 0; s < kCieSamples; ++s) expect += h(kCie1931[s].lambda_nm) * F[s][j];
        const double diff = d.film_rgb[j] - expect;
        film_sum[j] += diff;
        film_sum2[j] += diff * diff;
        expect_sum[j] += expect;
      }
    }
  }
  const double n = double(in.size() - first_random);
  for (int j = 0; j < 3; ++j) {
    const double mean = film_sum[j] / n, se = std::sqrt((film_sum2[j] / n - mean * mean) / (n - 1));
    EXPECT_LT(std::fabs(mean), 4 * se) << "channel " << j << " (mean colour " << expect_sum[j] / n << ")";
  }
}

}  // namespace
}  // namespace spectrack
