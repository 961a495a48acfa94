// test_guiding_fit.cpp: the weighted EM fit of src/guiding/vmf_fit.h.
//   - the inverse of the mean resultant length is exact (Banerjee's start, Newton's finish);
//   - EM recovers a known 3-lobe mixture from its own samples, and from uniform samples weighted
//     by its pdf (the form of radiance records), within 4 standard errors of each parameter
//     (kappa: 1 / sqrt(n A'(kappa)); weight: binomial; mean: the tangent-plane spread); twins: the
//     same fit compared with kappas or weights 3% off fails;
//   - the fit is deterministic (same input, same bits; weights in other units, same bits), and a handful of samples gives finite,
//     broad lobes (the MAP prior), no samples the uniform mixture.
#include <cstring>

#include "guiding/vmf_fit.h"
#include "guiding_util.h"

using namespace guiding_test;
using spectrack::DirectionalSample;
using spectrack::VmfFitOptions;

namespace {

const std::vector<LobeSpec> kTruth = {{unit(0.1, 0.2, 1), 60, 0.45}, {unit(1, -0.3, -0.2), 12, 0.35},
                                      {unit(-0.5, -0.8, -0.1), 300, 0.2}};

std::vector<DirectionalSample> draw(const st_vmf_mixture& m, int n, uint32_t seed) {
  Uniforms u(seed);
  std::vector<DirectionalSample> xs(n);
  for (auto& x : xs) {
    float u0 = u.next(), u1 = u.next(), u2 = u.next();
    st_vec3 w = vmf_mixture_sample(&m, u0, u1, u2);
    x = {{w.x, w.y, w.z}, 1.0f};
  }
  return xs;
}

// The fitted lobe nearest to each true lobe, and whether every parameter is within 4 SE of
// `truth` (kappas scaled by kappa_scale, weights by weight_scale: the twins). n_eff[k]: the
// effective number of samples behind true lobe k.
bool recovered(const st_vmf_mixture& fit, const std::vector<LobeSpec>& truth, const std::vector<double>& n_eff,
               double kappa_scale, double weight_scale, bool report) {
  bool ok = true;
  for (size_t k = 0; k < truth.size(); ++k) {
    int best = 0;
    for (int j = 1; j < ST_VMF_LOBES; ++j)
      if (dot(unit(fit.lobe[j].x, fit.lobe[j].y, fit.lobe[j].z), truth[k].mu) >
          dot(unit(fit.lobe[best].x, fit.lobe[best].y, fit.lobe[best].z), truth[k].mu))
        best = j;
    const double kap = truth[k].kappa * kappa_scale, w = truth[k].weight * weight_scale, n = n_eff[k];
    const double se_kappa = 1 / std::sqrt(n * (1 / (kap * kap) - 1 / std::pow(std::sinh(kap), 2)));
    const double se_weight = std::sqrt(truth[k].weight * (1 - truth[k].weight) / (n / truth[k].weight));
    // the mean's tangent-plane error: two axes of variance 1 / (n kappa A(kappa)); P(chi2_2 > 18.4) = 1e-4
    const double max_angle = std::sqrt(18.4 / (n * kap * spectrack::vmf_mean_cosine(kap)));
    const D3 mu = unit(fit.lobe[best].x, fit.lobe[best].y, fit.lobe[best].z);
    const double angle = std::acos(std::min(1.0, dot(mu, truth[k].mu)));
    bool lobe_ok = std::fabs(fit.lobe[best].w - kap) < 4 * se_kappa && std::fabs(fit.weight[best] - w) < 4 * se_weight &&
                   angle < max_angle;
    if (report && !lobe_ok)
      ADD_FAILURE() << "lobe " << k << ": kappa " << fit.lobe[best].w << " vs " << kap << " (SE " << se_kappa
                    << "), weight " << fit.weight[best] << " vs " << w << " (SE " << se_weight << "), angle " << angle
                    << " (max " << max_angle << ")";
    ok = ok && lobe_ok;
  }
  return ok;
}

}  // namespace

TEST(GuidingFit, MeanCosineInverseIsExact) {
  for (double kappa : {1e-6, 1e-4, 1e-2, 0.3, 1.0, 4.0, 30.0, 500.0, 1e4}) {
    double r = spectrack::vmf_mean_cosine(kappa);
    EXPECT_NEAR(spectrack::vmf_kappa_from_mean_cosine(r), kappa, 1e-8 * kappa) << kappa;
  }
  EXPECT_EQ(spectrack::vmf_kappa_from_mean_cosine(0.0), 0.0);
}

TEST(GuidingFit, RecoversAMixtureFromItsSamples) {
  const int n = 300000;
  std::vector<DirectionalSample> xs = draw(make_mixture(kTruth), n, 11);
  VmfFitOptions o;
  o.lobes = 3;
  spectrack::VmfFitResult r = spectrack::fit_vmf_mixture(xs, o);
  std::vector<double> n_eff;
  for (const auto& l : kTruth) n_eff.push_back(l.weight * n);
  EXPECT_TRUE(recovered(r.mixture, kTruth, n_eff, 1.0, 1.0, true)) << r.iterations << " iterations";
  EXPECT_FALSE(recovered(r.mixture, kTruth, n_eff, 1.03, 1.0, false)) << "twin: kappas 3% off must fail";
  EXPECT_FALSE(recovered(r.mixture, kTruth, n_eff, 1.0, 1.03, false)) << "twin: weights 3% off must fail";
}

TEST(GuidingFit, RecoversAMixtureFromWeightedUniformSamples) {
  // radiance records in miniature: uniform directions weighted by the true pdf over 1/4pi
  const std::vector<LobeSpec> truth = {{unit(0.3, 0.1, 1), 20, 0.6}, {unit(-0.4, -1, -0.2), 6, 0.4}};
  const st_vmf_mixture m = make_mixture(truth);
  const int n = 1500000;
  Uniforms u(12);
  std::vector<DirectionalSample> xs(n);
  std::vector<double> sum(truth.size(), 0.0), sum2(truth.size(), 0.0);
  for (auto& x : xs) {
    float u1 = u.next(), u2 = u.next();
    st_vec3 w = vmf_sample(vec3_make(0, 0, 1), 0.0f, u1, u2);
    x = {{w.x, w.y, w.z}, float(vmf_mixture_pdf(&m, w) / ST_GUIDE_INV_4PI)};
    for (size_t k = 0; k < truth.size(); ++k) {  // lobe k's share of the weight: its responsibility
      double s = truth[k].weight * vmf_eval(to_vec3(truth[k].mu), float(truth[k].kappa), w) / ST_GUIDE_INV_4PI;
      sum[k] += s, sum2[k] += s * s;
    }
  }
  std::vector<double> n_eff;  // Kish's effective count of each lobe's weighted samples
  for (size_t k = 0; k < truth.size(); ++k) n_eff.push_back(sum[k] * sum[k] / sum2[k]);
  VmfFitOptions o;
  o.lobes = 2;
  spectrack::VmfFitResult r = spectrack::fit_vmf_mixture(xs, o);
  EXPECT_TRUE(recovered(r.mixture, truth, n_eff, 1.0, 1.0, true)) << r.iterations << " iterations";
  EXPECT_FALSE(recovered(r.mixture, truth, n_eff, 1.03, 1.0, false)) << "twin: kappas 3% off must fail";
  EXPECT_FALSE(recovered(r.mixture, truth, n_eff, 1.0, 1.03, false)) << "twin: weights 3% off must fail";
}

TEST(GuidingFit, IsDeterministic) {
  std::vector<DirectionalSample> xs = draw(make_mixture(kTruth), 20000, 13);
  for (size_t i = 0; i < xs.size(); ++i) xs[i].weight = 0.5f + float(i % 7);
  spectrack::VmfFitResult a = spectrack::fit_vmf_mixture(xs), b = spectrack::fit_vmf_mixture(xs);
  EXPECT_EQ(std::memcmp(&a.mixture, &b.mixture, sizeof(st_vmf_mixture)), 0);
  EXPECT_EQ(a.iterations, b.iterations);
  std::vector<DirectionalSample> scaled = xs;  // records in other units: weights x 4 (exact in float)
  for (auto& x : scaled) x.weight *= 4.0f;
  spectrack::VmfFitResult d = spectrack::fit_vmf_mixture(scaled);
  EXPECT_EQ(std::memcmp(&a.mixture, &d.mixture, sizeof(st_vmf_mixture)), 0) << "the fit depends on relative weights only";
  VmfFitOptions other;
  other.seed = 2;  // another initialisation: another (valid) fit, so the comparison above can fail
  spectrack::VmfFitResult c = spectrack::fit_vmf_mixture(xs, other);
  EXPECT_NE(std::memcmp(&a.mixture, &c.mixture, sizeof(st_vmf_mixture)), 0);
}

TEST(GuidingFit, FewSamplesGiveBroadFiniteLobes) {
  const st_vmf_mixture none = spectrack::fit_vmf_mixture({}).mixture;
  EXPECT_FLOAT_EQ(vmf_mixture_pdf(&none, vec3_make(1, 0, 0)), ST_GUIDE_INV_4PI) << "no samples: uniform";
  for (int n : {1, 2, 5}) {
    std::vector<DirectionalSample> xs;
    for (int i = 0; i < n; ++i) xs.push_back({{0.0f, 0.6f, 0.8f}, 3.0f});
    st_vmf_mixture m = spectrack::fit_vmf_mixture(xs).mixture;
    float total = 0;
    for (int k = 0; k < ST_VMF_LOBES; ++k) {
      total += m.weight[k];
      EXPECT_TRUE(std::isfinite(m.lobe[k].w)) << n;
      EXPECT_LT(m.lobe[k].w, 50.0f * n) << n << " samples: the prior keeps kappa of the order of the evidence";
    }
    EXPECT_NEAR(total, 1.0f, 1e-5f);
  }
}
