// test_guiding.cpp: the von Mises-Fisher mixture of kernels/guiding.h on the host (the device runs
// the same header: test_guiding_cl.cpp; the fit: test_guiding_fit.cpp).
//   - a lobe's pdf integrates to 1 over the sphere for kappa from 0 to 1e4, and so does a mixture
//     of 8 lobes with weights that do not sum to 1; twins: a pdf 3% off, and the normaliser
//     written without expm1 at small kappa, fail the same check;
//   - sampling follows the pdf: chi-square over a binned sphere (a lobe, in quantile bins of its
//     polar angle; a mixture, in equal-area bins), at alpha = 1e-4; twin: the same counts against
//     a pdf that moves 3% of the mass is rejected;
//   - the one-sample mixture of Henyey-Greenstein and a guide, weighed by
//     f_phase / (alpha p_guide + (1 - alpha) p_phase), estimates the integral of f_phase g within
//     4 standard errors for a good guide, a guide pointing away from g and an empty one; twin: the
//     pdf 3% off is detected;
//   - SPECTRACK_GUIDE_DEPTH is read strictly (a count, or 0 for every event; anything else is an
//     error naming the variable).
#include <algorithm>
#include <cstdlib>
#include <limits>
#include <map>

#include "guiding/guide_cache.h"
#include "guiding_util.h"
#include "util/error.h"

using namespace guiding_test;

namespace {

// Chi-square of counts against probabilities, bins with expected count below 5 pooled.
std::pair<double, double> chi_square(const std::vector<double>& p, const std::vector<double>& counts) {
  double n = 0, chi2 = 0, pool_e = 0, pool_o = 0;
  for (double c : counts) n += c;
  int bins = 0;
  for (size_t b = 0; b < p.size(); ++b) {
    double e = n * p[b];
    if (e < 5) {
      pool_e += e, pool_o += counts[b];
      continue;
    }
    chi2 += (counts[b] - e) * (counts[b] - e) / e, ++bins;
  }
  if (pool_e > 0) chi2 += (pool_o - pool_e) * (pool_o - pool_e) / std::max(pool_e, 1e-300), ++bins;
  return {chi2, double(bins - 1)};
}

// 3% of the probability moved from the bins with sign -1 to those with sign +1.
std::vector<double> tilted(const std::vector<double>& p, const std::vector<int>& sign) {
  std::vector<double> q(p.size());
  double s = 0;
  for (size_t b = 0; b < p.size(); ++b) s += (q[b] = p[b] * (1 + 0.03 * sign[b]));
  for (double& x : q) x /= s;
  return q;
}

// t = 1 - cos of the angle between w and the unit axis n, from the angle itself (independent of
// |w|, which float rounding moves by ~1e-7: as much as a bin of a kappa 1e4 lobe near its mean).
double polar_t(const D3& w, const D3& n) {
  D3 c = {w[1] * n[2] - w[2] * n[1], w[2] * n[0] - w[0] * n[2], w[0] * n[1] - w[1] * n[0]};
  double th = std::atan2(std::sqrt(dot(c, c)), dot(w, n));
  return 2 * std::sin(0.5 * th) * std::sin(0.5 * th);
}

// The integral over [lo, hi] of f, on panels that halve toward lo (where a lobe's mass is).
double integral_from(double lo, double hi, const std::function<double(double)>& f) {
  double s = 0;
  for (int j = 0; j <= 40; ++j) {
    double a = lo + (hi - lo) * (j == 40 ? 0.0 : std::ldexp(1.0, -j - 1)), b = lo + (hi - lo) * std::ldexp(1.0, -j);
    s += gauss(a, b, f);
  }
  return s;
}

double lobe_integral(st_vec3 mu, float kappa, double scale, bool naive) {
  D3 n = to_d3(mu);
  n = unit(n[0], n[1], n[2]);
  return sphere_integral_around(n, 8, [&](const D3& w) {
    if (!naive) return scale * vmf_eval(mu, kappa, to_vec3(w));
    float t = float(one_minus_cos(w, n));  // the normaliser with 1 - exp(-2 kappa): cancels at small kappa
    return double(kappa / (2.0f * ST_GUIDE_PI * (1.0f - std::exp(-2.0f * kappa))) * std::exp(-kappa * t));
  });
}

}  // namespace

TEST(GuidingVmf, LobeIntegratesToOneForEveryKappa) {
  const double tol = 1e-6;  // the float pdf rounds by ~1e-7 per evaluation; the quadrature is exact to 1e-8
  const float kappas[] = {0.0f, 1e-6f, 1e-4f, 1e-3f, 1e-2f, 0.1f, 1.0f, 10.0f, 100.0f, 1e3f, 1e4f};
  const D3 axes[] = {unit(0, 0, 1), unit(0, 0, -1), unit(0.3, -0.5, 0.81), unit(-1, 0.01, -0.02)};
  for (float kappa : kappas)
    for (const D3& a : axes) {
      SCOPED_TRACE(testing::Message() << "kappa " << kappa << " axis " << a[0] << "," << a[1] << "," << a[2]);
      st_vec3 mu = to_vec3(a);
      EXPECT_NEAR(lobe_integral(mu, kappa, 1.0, false), 1.0, tol);
      EXPECT_GT(std::fabs(lobe_integral(mu, kappa, 1.03, false) - 1.0), tol) << "twin: a pdf 3% off";
    }
  // twin: the normaliser with 1 - exp(-2 kappa) in float loses the small kappas
  EXPECT_GT(std::fabs(lobe_integral(to_vec3(axes[2]), 1e-6f, 1.0, true) - 1.0), tol);
}

TEST(GuidingVmf, MixtureIntegratesToOne) {
  Uniforms u(7);
  const double kappas[] = {0, 1e-4, 0.7, 4, 30, 250, 2e3, 1e4};
  std::vector<LobeSpec> spec;
  for (int k = 0; k < ST_VMF_LOBES; ++k)  // weights summing to 2.9: the mixture divides by their sum
    spec.push_back({unit(u.next() - 0.5, u.next() - 0.5, u.next() - 0.5), kappas[k], 0.1 + 0.2 * (k % 3) + 0.1 * k});
  spec[3].weight = 0;  // an unused lobe in the middle
  const st_vmf_mixture m = make_mixture(spec);
  auto total = [&](double scale) {
    double sum = 0;
    for (int j = 0; j < ST_VMF_LOBES; ++j) {
      if (m.weight[j] == 0) continue;
      D3 n = unit(m.lobe[j].x, m.lobe[j].y, m.lobe[j].z);
      // the mixture's pdf times lobe j's share of it (a partition of unity computed in double, in
      // the log domain): an integrand concentrated as lobe j, integrated in its frame
      sum += sphere_integral_around(n, 64, [&](const D3& w) {
        double lw[ST_VMF_LOBES], top = -INFINITY;
        for (int i = 0; i < ST_VMF_LOBES; ++i) {
          double kap = m.lobe[i].w;
          D3 mi = unit(m.lobe[i].x, m.lobe[i].y, m.lobe[i].z);
          double ln = kap > 0 ? std::log(kap / (2 * kPi * -std::expm1(-2 * kap))) : std::log(1 / (4 * kPi));
          lw[i] = m.weight[i] > 0 ? std::log(double(m.weight[i])) + ln - kap * one_minus_cos(w, mi) : -INFINITY;
          top = std::max(top, lw[i]);
        }
        double s = 0;
        for (double x : lw) s += std::exp(x - top);
        return scale * vmf_mixture_pdf(&m, to_vec3(w)) * std::exp(lw[j] - top) / s;
      });
    }
    return sum;
  };
  EXPECT_NEAR(total(1.0), 1.0, 1e-6);
  EXPECT_GT(std::fabs(total(1.03) - 1.0), 1e-6) << "twin: a pdf 3% off";
  st_vmf_mixture empty{};
  EXPECT_FLOAT_EQ(vmf_mixture_pdf(&empty, vec3_make(0, 1, 0)), ST_GUIDE_INV_4PI) << "no weight: uniform";
}

namespace {

// The expected probabilities of a lobe's bins (NT quantile bins of t = 1 - cos theta, of equal
// mass under the exact CDF, times NP azimuth bins) by quadrature of the pdf under test, and the
// counts of n samples drawn by vmf_sample.
struct LobeBins {
  static constexpr int NT = 32, NP = 8;
  std::vector<double> p, counts;
  std::vector<int> sign;  // +1 for the inner half of the t bins: the twin moves mass inward
};

LobeBins bin_lobe(st_vec3 mu, float kappa, int n, uint32_t seed) {
  LobeBins r;
  const int NT = LobeBins::NT, NP = LobeBins::NP;
  D3 axis = to_d3(mu);
  axis = unit(axis[0], axis[1], axis[2]);
  D3 ft, fb;
  frame(axis, ft, fb);
  const double k = kappa;
  std::vector<double> edge(NT + 1);
  for (int i = 0; i <= NT; ++i) {
    double q = double(i) / NT;
    edge[i] = k > 1e-12 ? -std::log1p(q * std::expm1(-2 * k)) / k : 2 * q;
  }
  edge[NT] = 2;
  for (int i = 0; i < NT; ++i)
    for (int j = 0; j < NP; ++j) {
      double pr = integral_from(edge[i], edge[i + 1], [&](double t) {
        double s = 0;  // 4 azimuths inside the bin
        for (int a = 0; a < 4; ++a) s += vmf_eval(mu, kappa, to_vec3(around(axis, t, 2 * kPi * (j + (a + 0.5) / 4) / NP)));
        return s / 4 * 2 * kPi / NP;
      });
      r.p.push_back(pr);
      r.sign.push_back(i < NT / 2 ? 1 : -1);
    }
  r.counts.assign(r.p.size(), 0.0);
  Uniforms u(seed);
  for (int s = 0; s < n; ++s) {
    float u1 = u.next(), u2 = u.next();
    D3 w = to_d3(vmf_sample(mu, kappa, u1, u2));
    double t = polar_t(w, axis), phi = std::atan2(dot(w, fb), dot(w, ft));
    if (phi < 0) phi += 2 * kPi;
    int i = int(std::upper_bound(edge.begin(), edge.end(), t) - edge.begin()) - 1;
    int j = std::min(NP - 1, int(phi / (2 * kPi) * NP));
    r.counts[std::clamp(i, 0, NT - 1) * NP + j] += 1;
  }
  return r;
}

}  // namespace

TEST(GuidingSampling, LobeSamplesFollowItsPdf) {
  const float kappas[] = {0.0f, 1e-4f, 0.5f, 5.0f, 60.0f, 1e3f, 1e4f};
  const D3 axes[] = {unit(0, 0, 1), unit(0.3, -0.5, 0.81), unit(0.1, 0.2, -0.97)};
  uint32_t seed = 100;
  for (float kappa : kappas)
    for (const D3& a : axes) {
      SCOPED_TRACE(testing::Message() << "kappa " << kappa << " axis " << a[0] << "," << a[1] << "," << a[2]);
      LobeBins b = bin_lobe(to_vec3(a), kappa, 1000000, seed++);
      auto [chi2, dof] = chi_square(b.p, b.counts);
      EXPECT_LT(chi2, chi2_critical_1e4(dof)) << "dof " << dof;
      auto [twin, tdof] = chi_square(tilted(b.p, b.sign), b.counts);
      EXPECT_GT(twin, chi2_critical_1e4(tdof)) << "twin: 3% of the mass moved inward must be rejected";
    }
}

namespace {

// Chi-square of n directions of `sample` (three uniforms) in equal-area (z, phi) bins against the
// integral of `pdf` over each bin; the twin moves 3% of the mass to z > 0.
void expect_samples_follow(const std::function<double(st_vec3)>& pdf,
                           const std::function<st_vec3(float, float, float)>& sample) {
  const int NZ = 24, NPH = 48, n = 2000000;
  std::vector<double> p, counts(NZ * NPH, 0.0);
  std::vector<int> sign;
  for (int i = 0; i < NZ; ++i)
    for (int j = 0; j < NPH; ++j) {
      double z0 = -1 + 2.0 * i / NZ, z1 = -1 + 2.0 * (i + 1) / NZ;
      double pr = gauss(z0, z1, [&](double z) {
        return gauss(2 * kPi * j / NPH, 2 * kPi * (j + 1) / NPH, [&](double phi) {
          double r = std::sqrt(std::max(0.0, 1 - z * z));
          return pdf(to_vec3({r * std::cos(phi), r * std::sin(phi), z}));
        });
      });
      p.push_back(pr);
      sign.push_back(z0 >= 0 ? 1 : -1);
    }
  Uniforms u(31);
  for (int s = 0; s < n; ++s) {
    float u0 = u.next(), u1 = u.next(), u2 = u.next();
    D3 w = to_d3(sample(u0, u1, u2));
    double len = std::sqrt(dot(w, w)), phi = std::atan2(w[1], w[0]);
    if (phi < 0) phi += 2 * kPi;
    int i = std::clamp(int((w[2] / len + 1) / 2 * NZ), 0, NZ - 1), j = std::min(NPH - 1, int(phi / (2 * kPi) * NPH));
    counts[i * NPH + j] += 1;
  }
  auto [chi2, dof] = chi_square(p, counts);
  EXPECT_LT(chi2, chi2_critical_1e4(dof)) << "dof " << dof;
  auto [twin, tdof] = chi_square(tilted(p, sign), counts);
  EXPECT_GT(twin, chi2_critical_1e4(tdof)) << "twin: 3% of the mass moved to z > 0 must be rejected";
}

// lobes away from the poles and kappa <= 40, so Gauss-Legendre over (z, phi) bins resolves them
const st_vmf_mixture kBinnedMixture = make_mixture({{unit(1, 0, 0.2), 40, 0.5},
                                                    {unit(-0.3, 0.9, -0.4), 8, 1.1},
                                                    {unit(0.2, -0.7, 0.5), 2, 0.7},
                                                    {unit(-0.6, -0.5, -0.3), 0.01, 0.2},
                                                    {unit(0.5, 0.5, -0.6), 20, 0.0}});  // unused

}  // namespace

TEST(GuidingSampling, MixtureSamplesFollowItsPdf) {
  const st_vmf_mixture& m = kBinnedMixture;
  expect_samples_follow([&](st_vec3 w) { return double(vmf_mixture_pdf(&m, w)); },
                        [&](float u0, float u1, float u2) { return vmf_mixture_sample(&m, u0, u1, u2); });
}

// The product of the mixture with a phase lobe (the guide of events deeper than the first,
// kernels/guiding.h): its sampler follows its density, for the lobes of forward and backward
// Henyey-Greenstein functions.
TEST(GuidingSampling, PhaseProductSamplesFollowItsPdf) {
  const st_vmf_mixture& m = kBinnedMixture;
  const st_vec3 wo = to_vec3(unit(0.4, -0.3, 0.6));
  for (float g : {0.3f, 0.7f, -0.5f}) {
    SCOPED_TRACE(testing::Message() << "g " << g);
    const float kp = vmf_phase_kappa(g);
    const st_vec3 nu = g >= 0 ? wo : vec3_make(-wo.x, -wo.y, -wo.z);
    expect_samples_follow([&](st_vec3 w) { return double(guide_pdf(&m, nu, kp, w)); },
                          [&](float u0, float u1, float u2) { return guide_sample(&m, nu, kp, u0, u1, u2); });
  }
}

namespace {

struct Estimate {
  double mean, se, mean_twin;
};

// n samples of the one-sample mixture of HG (around wo) and the guide m, weighed by
// f_phase / p_mix; the twin divides by 1.03 p_mix.
Estimate guided_estimate(const st_vmf_mixture& m, float alpha, double g_hg, const D3& wo,
                         const std::function<double(const D3&)>& g, int n, uint32_t seed, bool product = false) {
  Uniforms u(seed);
  const float kp = product ? vmf_phase_kappa(float(g_hg)) : 0.0f;
  const st_vec3 nu = to_vec3(g_hg >= 0 ? wo : D3{-wo[0], -wo[1], -wo[2]});
  double s = 0, s2 = 0;
  for (int i = 0; i < n; ++i) {
    float u0 = u.next(), u1 = u.next(), u2 = u.next(), u_reuse;
    st_vec3 wi = guide_choose(alpha, u0, &u_reuse) ? guide_sample(&m, nu, kp, u_reuse, u1, u2)
                                                    : to_vec3(hg_sample(g_hg, wo, u1, u2));
    D3 w = to_d3(wi);
    double f = hg(g_hg, dot(wo, w) / std::sqrt(dot(w, w)));
    double pdf = guide_mixture_pdf(alpha, guide_pdf(&m, nu, kp, wi), float(f));
    double x = f / pdf * g(w);
    s += x, s2 += x * x;
  }
  double mean = s / n;
  return {mean, std::sqrt(std::max(0.0, s2 / n - mean * mean) / (n - 1)), mean / 1.03};
}

}  // namespace

TEST(GuidingMixture, OneSampleEstimatorIsUnbiasedForAnyGuide) {
  const D3 wo = unit(0.2, 0.1, 1), light = unit(-0.7, 0.6, 0.3);
  const double g_hg = 0.6;
  // the test function: a dim sky and a bright light of angular radius ~0.3 rad
  auto g = [&](const D3& w) { return 0.2 + 5 * std::exp(12 * (dot(w, light) - 1)); };
  const double reference = phase_times_g(g_hg, wo, g);
  const D3 away = {-light[0], -light[1], -light[2]};
  struct Case {
    const char* name;
    st_vmf_mixture m;
  } cases[] = {{"good", make_mixture({{light, 12, 0.8}, {wo, 1, 0.2}})},
               {"pointing away", make_mixture({{away, 50, 0.7}, {unit(0, -1, 0.1), 300, 0.3}})},
               {"empty", make_mixture({})}};
  uint32_t seed = 500;
  for (const Case& c : cases)
    for (float alpha : {0.1f, 0.5f, 0.9f})
      for (bool product : {false, true}) {
      SCOPED_TRACE(testing::Message() << c.name << " alpha " << alpha << " product " << product);
      // the product's lobe makes a wrong guide's weights heavier: more samples for the twin's power
      Estimate e = guided_estimate(c.m, alpha, g_hg, wo, g, product ? 2000000 : 1000000, seed++, product);
      EXPECT_NEAR(e.mean, reference, 4 * e.se) << "SE " << e.se;
      EXPECT_GT(std::fabs(e.mean_twin - reference), 4 * e.se) << "twin: the pdf 3% off must be detected";
    }
}

// Where the incident radiance does not depend on the direction (deep in a dense medium) a region's
// fit is about uniform, and guiding cannot remove variance: the guided weight W = f_phase / p_mix
// must then stay close to 1, or its second moment E[W^2] = E_f[f / p_mix] compounds over a random
// walk's events (M2^n). With the phase product the uniform guide becomes the phase lobe: M2 within
// 0.5% of 1 for g = 0.3 (and 7% for g = 0.7 where one lobe fits Henyey-Greenstein less well);
// twin: the guide without the product (the uniform density itself) gives M2 = 1.068 and 1.378.
TEST(GuidingMixture, UniformRadianceKeepsTheGuidedWeightNearOneWithThePhaseProduct) {
  const st_vmf_mixture uniform = make_mixture({{unit(0, 0, 1), 1e-6f, 1.0}});
  const D3 wo = unit(0.2, -0.4, 0.9);
  for (double g_hg : {0.3, 0.7}) {
    for (bool product : {true, false}) {
      const float kp = product ? vmf_phase_kappa(float(g_hg)) : 0.0f;
      Uniforms u(900);
      double s = 0;
      const int n = 400000;
      for (int i = 0; i < n; ++i) {
        const D3 w = hg_sample(g_hg, wo, u.next(), u.next());
        const double f = hg(g_hg, dot(wo, w) / std::sqrt(dot(w, w)));
        s += f / guide_mixture_pdf(0.5f, guide_pdf(&uniform, to_vec3(wo), kp, to_vec3(w)), float(f));
      }
      const double m2 = s / n, bound = g_hg < 0.5 ? 1.005 : 1.07;
      SCOPED_TRACE(testing::Message() << "g " << g_hg << " product " << product << " M2 " << m2);
      if (product) EXPECT_LT(m2, bound);
      else EXPECT_GT(m2, bound) << "twin: the guide without the phase product must be seen to compound";
    }
  }
}

// The guided depth for measurements (SPECTRACK_GUIDE_DEPTH): a count, 0 for every event, and
// anything else refused by name rather than read as a depth.
TEST(GuidingDepthSetting, ReadsTheEnvironmentStrictly) {
  using spectrack::guide_depth_setting;
  ::unsetenv("SPECTRACK_GUIDE_DEPTH");
  EXPECT_EQ(guide_depth_setting(0), spectrack::kGuideDepth);
  EXPECT_EQ(guide_depth_setting(3), 3);
  EXPECT_EQ(guide_depth_setting(-1), std::numeric_limits<int>::max());
  ::setenv("SPECTRACK_GUIDE_DEPTH", "2", 1);
  EXPECT_EQ(guide_depth_setting(0), 2);
  ::setenv("SPECTRACK_GUIDE_DEPTH", "0", 1);
  EXPECT_EQ(guide_depth_setting(0), std::numeric_limits<int>::max());
  for (const char* bad : {"abc", "2x", "-1", "99999999999"}) {
    ::setenv("SPECTRACK_GUIDE_DEPTH", bad, 1);
    EXPECT_THROW(guide_depth_setting(0), spectrack::Error) << bad;
  }
  ::unsetenv("SPECTRACK_GUIDE_DEPTH");
}

// The bound on a training pass's recording samples (SPECTRACK_GUIDE_RECORD_SAMPLES): the default
// without it, a count read strictly, and the fraction it gives a pass.
TEST(GuidingDepthSetting, ReadsTheRecordSamplesStrictly) {
  using namespace spectrack;
  ::unsetenv("SPECTRACK_GUIDE_RECORD_SAMPLES");
  EXPECT_EQ(guide_record_samples_setting(), kGuideRecordSamples);
  ::setenv("SPECTRACK_GUIDE_RECORD_SAMPLES", "0", 1);
  EXPECT_EQ(guide_record_samples_setting(), 0);
  EXPECT_EQ(guide_record_fraction(4096 * 4096, 4, guide_record_samples_setting()), 1.0f) << "0: every sample records";
  ::setenv("SPECTRACK_GUIDE_RECORD_SAMPLES", "65536", 1);
  EXPECT_EQ(guide_record_fraction(256 * 256, 4, guide_record_samples_setting()), 0.25f);
  EXPECT_EQ(guide_record_fraction(128 * 128, 4, guide_record_samples_setting()), 1.0f);
  for (const char* bad : {"", "-1", " 5", "+5", "5x", "x", "99999999999999999999", "2e6"}) {
    ::setenv("SPECTRACK_GUIDE_RECORD_SAMPLES", bad, 1);
    if (*bad) EXPECT_THROW(guide_record_samples_setting(), Error) << bad;
    else EXPECT_EQ(guide_record_samples_setting(), kGuideRecordSamples);
  }
  ::unsetenv("SPECTRACK_GUIDE_RECORD_SAMPLES");
}

// The measurements' training schedule (SPECTRACK_GUIDE_TRAINING, SPECTRACK_GUIDE_TRAINING_KEEP) and
// switches (SPECTRACK_GUIDE_PRODUCT, SPECTRACK_GUIDE_FULL_PATH): read strictly, defaults without.
TEST(GuidingDepthSetting, ReadsTheTrainingScheduleAndSwitchesStrictly) {
  using namespace spectrack;
  for (const char* v : {"SPECTRACK_GUIDE_TRAINING", "SPECTRACK_GUIDE_TRAINING_KEEP", "SPECTRACK_GUIDE_PRODUCT",
                        "SPECTRACK_GUIDE_FULL_PATH"})
    ::unsetenv(v);
  GuideTraining t = guide_training_setting();
  EXPECT_EQ(t.spp, std::vector<int>(kGuideTrainingSpp, kGuideTrainingSpp + kGuideTrainingPasses));
  EXPECT_TRUE(t.keep);
  EXPECT_FALSE(guide_phase_product_setting(1));  // the mixture alone, whose alpha is learned
  EXPECT_FALSE(guide_phase_product_setting(2));  // at every depth
  EXPECT_FALSE(guide_full_path_setting(false));
  EXPECT_FALSE(guide_full_path_setting(true));  // measurements only (guide_cache.h)
  ::setenv("SPECTRACK_GUIDE_TRAINING", "4,8,16", 1);
  ::setenv("SPECTRACK_GUIDE_TRAINING_KEEP", "0", 1);
  ::setenv("SPECTRACK_GUIDE_PRODUCT", "1", 1);
  ::setenv("SPECTRACK_GUIDE_FULL_PATH", "0", 1);
  t = guide_training_setting();
  EXPECT_EQ(t.spp, (std::vector<int>{4, 8, 16}));
  EXPECT_FALSE(t.keep);
  EXPECT_TRUE(guide_phase_product_setting(1));
  EXPECT_FALSE(guide_full_path_setting(true));
  for (const char* bad : {"", "4,", "4,,8", "x", "0", "4;8"}) {
    ::setenv("SPECTRACK_GUIDE_TRAINING", bad, 1);
    if (*bad) EXPECT_THROW(guide_training_setting(), Error) << bad;
    else EXPECT_NO_THROW(guide_training_setting());
  }
  ::setenv("SPECTRACK_GUIDE_PRODUCT", "yes", 1);
  EXPECT_THROW(guide_phase_product_setting(1), Error);
  for (const char* v : {"SPECTRACK_GUIDE_TRAINING", "SPECTRACK_GUIDE_TRAINING_KEEP", "SPECTRACK_GUIDE_PRODUCT",
                        "SPECTRACK_GUIDE_FULL_PATH"})
    ::unsetenv(v);
}
