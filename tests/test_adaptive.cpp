// test_adaptive.cpp: adaptive sampling (integrator/adaptive.h).
//
// Design: the weighting is checked on a simulated pixel whose radiance is a rare bright event (the
// case where a pixel's own pilot looks converged when it is not): over many independent pixels the
// weighted estimate's mean agrees with the true mean within 4 SE, while the plain average of the
// same samples, stopped by the same rule, is seen to be biased, and so is a 3% error (the twins).
// A render then checks the whole path: it reaches its target with fewer samples than the cap on
// average, agrees with a long uniform render of another seed within 4 SE (a 3% error does not),
// and repeats to the bit; a round's list of entries draws each entry's own samples. The command line writes the samples layer and the metadata, and refuses
// what cannot work with adaptive sampling (exit 2), merges included.
#include <OpenImageIO/imageio.h>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <random>

#include "cli_util.h"
#include "guiding/guide_cache.h"
#include "integrator/adaptive.h"
#include "integrator/noise.h"
#include "integrator/renderer.h"

namespace {

using namespace st_cli;
using namespace spectrack;

struct PixelRun {
  double weighted = 0, averaged = 0;
  int64_t n = 0;
  double V = 0;  // sum of a_r^2 / k_r: the estimate's variance over one sample's
  bool pilot_varied = false;  // the pilot drew the rare value (its sample variance is not 0)
};

// A round of k simulated samples: 1, or 40 with probability 0.02 (mean 1.78).
AdaptivePixel simulate_round(std::mt19937_64& rng, int64_t k) {
  std::bernoulli_distribution rare(0.02);
  AdaptivePixel r;
  for (int64_t i = 0; i < k; ++i) {
    const double y = rare(rng) ? 40.0 : 1.0;
    r.s1[0] += y;
    r.s2[0] += y * y;
  }
  r.n = k;
  return r;
}

// How a simulated pixel's pilot is weighted: k_0 / spp, from 8 neighbours' pilots
// (adaptive_pilot_weights), or, the twin, from its own pilot put in the neighbours' places.
// kHeavy gives the pilot the weight `heavy`, many times its share: pixels whose pilot drew the
// rare path can then no longer reach their aim (rho V >= aim^2), nor, with a heavier one, the target.
enum class PilotWeight { kFixed, kNeighbours, kOwnPilot, kHeavy };

// One simulated pixel (simulate_round's samples), taken in the rounds and with the weights of
// adaptive.h, deciding from its own samples.
PixelRun simulate_pixel(std::mt19937_64& rng, const AdaptivePlan& plan, PilotWeight pilot = PilotWeight::kFixed,
                        double heavy = 0) {
  AdaptivePixel px;
  PixelRun out;
  while (!px.done()) {
    const double rho = adaptive_relative_variance(px, 0.0);
    const int64_t round = adaptive_round_samples(px.n, plan);
    double a = adaptive_round_weight(px, round, plan.spp, rho, plan);
    const int64_t k = adaptive_round_length(px, round, plan.spp, rho, plan);
    const AdaptivePixel r = simulate_round(rng, k);
    const double s1 = r.s1[0], s2 = r.s2[0];
    if (px.n == 0 && pilot == PilotWeight::kHeavy) a = heavy;
    if (px.n == 0 && (pilot == PilotWeight::kNeighbours || pilot == PilotWeight::kOwnPilot)) {
      std::vector<AdaptivePixel> grid(9);
      for (AdaptivePixel& q : grid) {
        q = pilot == PilotWeight::kOwnPilot ? r : simulate_round(rng, k);
        for (int c = 1; c < 3; ++c) q.s1[c] = q.s1[0], q.s2[c] = q.s2[0];
      }
      a = adaptive_pilot_weights(grid, 3, 3, plan)[4];
    }
    out.weighted += a * s1 / double(k);
    const double r1[3] = {s1, s1, s1}, r2[3] = {s2, s2, s2};
    adaptive_add_round(px, a, k, r1, r2);
    if (px.n == k) out.pilot_varied = px.sample_variance(0) > 0.0;
  }
  out.averaged = px.s1[0] / double(px.n);
  out.n = px.n;
  out.V = px.V;
  return out;
}

// The pilot's weight from the neighbours' pilots: unbiased, and it wastes fewer samples than k_0 /
// spp; the twin takes it from the pixel's own pilot (put in its neighbours' places) and is biased.
TEST(AdaptiveWeights, APilotWeightFromTheNeighboursIsUnbiasedWhereOneFromTheOwnPilotIsNot) {
  const double mu = 0.98 * 1.0 + 0.02 * 40.0;
  AdaptivePlan plan;
  plan.target = 0.3;  // about 160 samples a pixel: the pilot is a tenth of them
  plan.spp = 1024;
  plan.pilot = 16;
  const int kPixels = 100000;
  std::mt19937_64 rng(777);
  std::vector<double> neighbours, own;
  int64_t samples_fixed = 0, samples_neighbours = 0;
  for (int t = 0; t < kPixels; ++t) {
    samples_fixed += simulate_pixel(rng, plan, PilotWeight::kFixed).n;
    const PixelRun r = simulate_pixel(rng, plan, PilotWeight::kNeighbours);
    neighbours.push_back(r.weighted);
    samples_neighbours += r.n;
    own.push_back(simulate_pixel(rng, plan, PilotWeight::kOwnPilot).weighted);
  }
  const st_test::Stats w = st_test::mean_se(neighbours), o = st_test::mean_se(own);
  EXPECT_LT(std::abs(w.mean - mu) / w.se, 4.0) << "weighted mean " << w.mean << " vs " << mu;
  EXPECT_GT(std::abs(1.03 * w.mean - mu) / w.se, 4.0) << "the twin: a 3% error must be seen";
  EXPECT_GT(std::abs(o.mean - mu) / o.se, 4.0) << "the twin: a pilot weighted from itself is biased (" << o.mean << ")";
  EXPECT_LT(samples_neighbours, samples_fixed) << "the neighbours' weight wastes less of the pilot";
}

// A pixel whose fixed weights already hold more variance than its aim allows aims at the target,
// or, out of reach of that too, takes the samples that add no more variance than its fixed weights
// hold (B^2 / T = V), instead of running to the spp (a rule before did: 27604 of these 100000
// pixels took all 4096 samples with the heavier pilot) or finishing with a quarter round that
// takes all the weight left (the rule after it: the pilot's fixed variance times 65 on average, an
// error 8 times the least reachable): the decision is made before the round from the rounds so
// far, so the estimate stays unbiased.
TEST(AdaptiveWeights, PixelsThatCannotReachTheirAimStopWithoutBias) {
  const double mu = 0.98 * 1.0 + 0.02 * 40.0;
  AdaptivePlan plan;
  plan.target = 0.1;  // rho about 9.4: about 1160 samples at the aim
  plan.spp = 4096;
  plan.pilot = 16;
  const int kPixels = 100000;
  std::mt19937_64 rng(4242);
  // 0.125: one rare path in the pilot leaves the aim just in reach, more rounds put some pixels
  // out of it; 0.2: one rare path in the pilot puts the target itself out of reach
  for (const double heavy : {0.125, 0.2}) {
    std::vector<double> est;
    int64_t at_spp = 0;
    double V_sum = 0;
    int64_t varied = 0;
    for (int t = 0; t < kPixels; ++t) {
      const PixelRun r = simulate_pixel(rng, plan, PilotWeight::kHeavy, heavy);
      est.push_back(r.weighted);
      at_spp += r.n >= plan.spp;
      if (r.pilot_varied) V_sum += r.V, ++varied;
    }
    if (heavy == 0.2) {
      EXPECT_EQ(at_spp, 0) << "pixels out of reach of the target ran to the spp";
      // a pilot that drew the rare value puts the target out of reach; the pilot alone holds
      // heavy^2 / 16 of the variance, the rule aims at twice that, and its later rounds' rho
      // estimates move it (about 3.2 times on average here; the quarter round was 65 times)
      ASSERT_GT(varied, kPixels / 5);
      const double V_pilot = heavy * heavy / double(plan.pilot), V_mean = V_sum / double(varied);
      EXPECT_LT(V_mean, 4.0 * V_pilot) << "pixels out of reach of the target gave up: V " << V_mean;
      EXPECT_GT(V_mean, V_pilot) << "the pilot's weight is fixed";
    }
    const st_test::Stats w = st_test::mean_se(est);
    EXPECT_LT(std::abs(w.mean - mu) / w.se, 4.0) << "pilot weight " << heavy << ": mean " << w.mean << " vs " << mu;
    EXPECT_GT(std::abs(1.03 * w.mean - mu) / w.se, 4.0) << "the twin: a 3% error must be seen";
  }
}

TEST(AdaptiveWeights, APilotWeightIgnoresThePixelsOwnPilot) {
  AdaptivePlan plan;
  plan.target = 0.05;
  plan.spp = 4096;
  plan.pilot = 16;
  // pilots of 16 samples of mean 1 and variance 0.25 (about 250 samples needed at the aim)
  AdaptivePixel noisy;
  noisy.n = 16;
  for (int c = 0; c < 3; ++c) noisy.s1[c] = 16.0, noisy.s2[c] = 16.0 + 0.25 * 15.0;
  std::vector<AdaptivePixel> grid(9, noisy);
  for (int c = 0; c < 3; ++c) grid[4].s2[c] += 25.0;  // a noisier centre
  const std::vector<double> w = adaptive_pilot_weights(grid, 3, 3, plan);
  AdaptivePixel quiet = grid[4];
  for (int c = 0; c < 3; ++c) quiet.s2[c] = quiet.s1[c] * quiet.s1[c] / 16.0;  // no variance
  std::vector<AdaptivePixel> other = grid;
  other[4] = quiet;
  EXPECT_EQ(adaptive_pilot_weights(other, 3, 3, plan)[4], w[4]) << "the centre's own pilot sets its weight";
  EXPECT_NE(adaptive_pilot_weights(other, 3, 3, plan)[0], w[0]) << "a neighbour's pilot does not";
  EXPECT_GT(w[4], 16.0 / 4096.0);
  EXPECT_LE(w[4], 1.0 / kAdaptivePilotMin);
  EXPECT_NEAR(w[4], 16.0 / (kAdaptivePilotMargin * 0.25 / std::pow(0.05 * kAdaptiveAim, 2)), 1e-12);
  // no noisy neighbour: k_0 / spp, as if the pixel took every sample
  std::vector<AdaptivePixel> calm(9, quiet);
  calm[4] = grid[4];
  EXPECT_DOUBLE_EQ(adaptive_pilot_weights(calm, 3, 3, plan)[4], 16.0 / 4096.0);
}

// The per-pixel cap is the need of the 97.5th-percentile pixel: half of the 5% the image's
// percentile allows above the target goes to the pixels it stops, half is left for drift.
TEST(AdaptiveCap, LeavesHalfThePercentilesAllowanceToDrift) {
  AdaptivePlan plan;
  plan.target = 0.05;
  plan.spp = 4096;
  AdaptivePixel x;  // 16 samples of mean 1 and some variance: a counted pixel
  x.n = 16;
  for (int c = 0; c < 3; ++c) x.s1[c] = 16.0, x.s2[c] = 20.0;
  const double e2 = std::pow(plan.target * plan.aim, 2);
  std::vector<AdaptivePixel> px(200, x);
  std::vector<double> rho(200);
  for (size_t i = 0; i < rho.size(); ++i) rho[i] = double(i) * 10.0 * e2 * (1.0 - 1e-9);  // needs 10 i more
  // nearest rank: the 195th of 200 needs (0-based 194) 16 + 1940; the 95th percentile's is 16 + 1890
  EXPECT_EQ(adaptive_cap(px, rho, plan), 16 + 1940);
  // needs that grow steeply past the 95th percentile: at most twice its need
  for (size_t i = 190; i < rho.size(); ++i) rho[i] *= 100.0;
  EXPECT_EQ(adaptive_cap(px, rho, plan), 2 * (16 + 1890));
}

// A counted pixel of 100 samples, relative variance `rho` per sample (mean 1), with the weights
// V and B left, and the error its last round was predicted to bring it to.
AdaptivePixel aim_pixel(double rho, double V, double B, double predicted = 0) {
  AdaptivePixel x;
  x.n = 100;
  for (int c = 0; c < 3; ++c) x.s1[c] = 100.0, x.s2[c] = 100.0 + 99.0 * rho;
  x.V = V;
  x.B = B;
  x.predicted = predicted;
  x.decided = predicted > 0 ? 100 : 0;
  return x;
}

std::vector<double> own_rho(const std::vector<AdaptivePixel>& px) {
  std::vector<double> rho;
  for (const AdaptivePixel& x : px) rho.push_back(adaptive_relative_variance(x, 0.0));
  return rho;
}

// The aim follows the measured drift: plan.aim until kAdaptiveDriftMin pixels have finished at an
// aim; then higher where they ended close to their predicted errors, and plan.aim where many
// drifted far above them.
TEST(AdaptiveAim, RisesOnlyAsFarAsTheMeasuredDriftAllows) {
  AdaptivePlan plan;
  plan.target = 0.05;
  plan.spp = 4096;
  // finished pixels measure sqrt(0.25 * 0.008) = 0.0447; active ones need 34 samples at the target
  const double measured = std::sqrt(0.25 * 0.008);
  std::vector<AdaptivePixel> px(400, aim_pixel(0.25, 0.0025, 0.5));
  EXPECT_EQ(adaptive_aim(px, own_rho(px), 0.0, plan).aim, plan.aim) << "no pixel has finished";
  // 100 pixels finished exactly at their predicted error: no drift, the aim rises to 1
  for (size_t i = 0; i < 100; ++i) px[i] = aim_pixel(0.25, 0.008, 0, measured);
  EXPECT_EQ(adaptive_aim(px, own_rho(px), 0.0, plan).aim, 1.0);
  // too few finished pixels to go on
  std::vector<AdaptivePixel> few(px.begin() + 100 - std::ptrdiff_t(kAdaptiveDriftMin) + 1, px.end());
  EXPECT_EQ(adaptive_aim(few, own_rho(few), 0.0, plan).aim, plan.aim);
  // a third of them ended 20% above their prediction: the aim stays where it was
  for (size_t i = 0; i < 100; i += 3) px[i].predicted = measured / 1.2;
  EXPECT_EQ(adaptive_aim(px, own_rho(px), 0.0, plan).aim, plan.aim);
  // 5% of them 4% above: an aim below 1 that leaves those above the target
  for (size_t i = 0; i < 100; ++i) px[i].predicted = i % 20 == 0 ? measured / 1.04 : measured;
  const double aim = adaptive_aim(px, own_rho(px), 0.0, plan).aim;
  EXPECT_GT(aim, plan.aim);
  EXPECT_LE(aim, 1.0 / 1.04);
  // finished pixels above the target take their part of the allowance (20 of 400): with no drift
  // the aim is 1, with more of them above the target than it allows, plan.aim
  for (size_t i = 0; i < 100; ++i) px[i].predicted = measured;
  EXPECT_EQ(adaptive_aim(px, own_rho(px), 0.0, plan).aim, 1.0);
  for (size_t i = 0; i < 21; ++i) px[i * 4 + 1] = aim_pixel(0.25, 0.0121, 0, 0.055);
  EXPECT_EQ(adaptive_aim(px, own_rho(px), 0.0, plan).aim, plan.aim);
}

// The pixels the cap stops count by the error it leaves them at: those it leaves below the target
// (their need at the aim above the cap, at the target below it) take of the allowance only what
// their drift may carry above it, so the aim can rise where the rule before reserved half the
// allowance for them; those it leaves far above the target take a pixel each.
TEST(AdaptiveAim, CountsThePixelsTheCapStopsByTheErrorItLeavesThemAt) {
  AdaptivePlan plan;
  plan.target = 0.05;
  plan.spp = 4096;
  const double measured = std::sqrt(0.25 * 0.008);
  // 100 finished pixels, 4% of them 4% above their prediction; 290 active ones needing 34 samples
  // at the target, 45 at the aim 0.9; 10 hard ones that need more than the cap (about 100 + 45)
  std::vector<AdaptivePixel> px(400, aim_pixel(0.25, 0.0025, 0.5));
  for (size_t i = 0; i < 100; ++i) px[i] = aim_pixel(0.25, 0.008, 0, i % 25 == 0 ? measured / 1.04 : measured);
  auto with_hard = [&](double rho) {
    std::vector<AdaptivePixel> film = px;
    for (size_t i = 390; i < 400; ++i) film[i] = aim_pixel(rho, 0.0025, 0.5);
    return film;
  };
  // the hard pixels left by the cap close to the target: their drift rarely carries them above it
  const std::vector<AdaptivePixel> near = with_hard(0.27);
  const AdaptivePlan round_near = adaptive_aim(near, own_rho(near), 0.0, plan);
  const std::vector<double> rho = own_rho(near);
  const int64_t cap = adaptive_cap(near, rho, round_near);
  EXPECT_GT(adaptive_samples_needed(near[395], rho[395], round_near), double(cap - 100)) << "the cap stops them";
  EXPECT_LT(adaptive_final_error(near[395], rho[395], cap, round_near), plan.target);
  // left far above the target (out of reach at the cap), they take 10 of the 20 allowed
  const std::vector<AdaptivePixel> far = with_hard(2.0);
  const double aim_far = adaptive_aim(far, own_rho(far), 0.0, plan).aim;
  EXPECT_GT(round_near.aim, aim_far) << "the pixels the cap leaves below the target cost the aim less";
  EXPECT_LE(aim_far, 1.0 / 1.04);
  EXPECT_GT(aim_far, plan.aim);
}

// A round of k samples of a light-tailed pixel: mean 1, standard deviation `sigma` (uniform).
AdaptivePixel simulate_calm_round(std::mt19937_64& rng, int64_t k, double sigma) {
  std::uniform_real_distribution<double> u(-0.5, 0.5);
  AdaptivePixel r;
  for (int64_t i = 0; i < k; ++i) {
    const double y = 1.0 + sigma * std::sqrt(12.0) * u(rng);
    r.s1[0] += y;
    r.s2[0] += y * y;
  }
  r.n = k;
  return r;
}

// The rule as a render runs it, on simulated films: the aim from the drift of the pixels that
// finished, the cap and its share from every pixel's need, a pixel's rounds from its own samples
// and its kind's (the neighbourhood of a render), all decided before the round they shape. Most
// pixels are light-tailed with needs from 4 to 900 samples, so they finish over many rounds and
// the aim rises; every 4th is the rare-event pixel. The weighted estimates of both kinds stay
// unbiased (4 SE, and a 3% error is seen). (The neighbourhood keeps the rare-event pixels going,
// so the plain average of their stopped samples is nearly unbiased here: the bias of that
// average is AreUnbiasedWhereAveragingAPixelsOwnStoppedSamplesIsNot's twin.)
TEST(AdaptiveWeights, TheDriftAwareAimAndTheCapAreUnbiased) {
  const double mu = 0.98 * 1.0 + 0.02 * 40.0;
  AdaptivePlan plan;
  plan.target = 0.1;
  plan.spp = 1024;
  std::mt19937_64 rng(4242);
  const int kFilms = 40, kPixels = 2000;
  std::vector<double> calm, rare;
  double aim_most = 0;
  for (int f = 0; f < kFilms; ++f) {
    std::vector<AdaptivePixel> px(kPixels);
    std::vector<double> est(kPixels, 0.0);
    auto sigma = [](int i) { return 0.2 + 2.8 * double(i % 97) / 96.0; };
    for (int64_t n = 0; n < plan.spp;) {
      const int64_t k = adaptive_round_samples(n, plan);
      std::vector<double> rho(kPixels);
      // a pixel's neighbours are of its kind: rho the larger of its own and its kind's mean (as
      // adaptive_neighbourhood), so that a rare-event pixel whose samples missed the event goes on
      double kind_sum[2] = {0, 0};
      for (int i = 0; i < kPixels; ++i) {
        rho[size_t(i)] = adaptive_relative_variance(px[size_t(i)], 0.0);
        kind_sum[i % 4 == 0] += rho[size_t(i)];
      }
      for (int i = 0; i < kPixels; ++i)
        rho[size_t(i)] = std::max(rho[size_t(i)], kind_sum[i % 4 == 0] / (i % 4 == 0 ? kPixels / 4 : kPixels - kPixels / 4));
      AdaptivePlan round = plan;
      if (n > 0) round = adaptive_aim(px, rho, 0.0, plan);
      aim_most = std::max(aim_most, round.aim);
      const int64_t cap = n == 0 ? plan.spp : adaptive_cap(px, rho, round);
      for (int i = 0; i < kPixels; ++i) {
        AdaptivePixel& p = px[size_t(i)];
        if (p.done() || p.n != n) continue;
        const double a = adaptive_round_weight(p, k, cap, rho[size_t(i)], round);
        const int64_t len = adaptive_round_length(p, k, cap, rho[size_t(i)], round);
        if (a >= p.B && n > 0) {
          p.predicted = std::sqrt(rho[size_t(i)] * (p.V + p.B * p.B / double(len)));
          p.decided = p.n;
        }
        AdaptivePixel r = i % 4 == 0 ? simulate_round(rng, len) : simulate_calm_round(rng, len, sigma(i));
        for (int c = 1; c < 3; ++c) r.s1[c] = r.s1[0], r.s2[c] = r.s2[0];
        est[size_t(i)] += a * r.s1[0] / double(len);
        adaptive_add_round(p, a, len, r.s1, r.s2);
      }
      n += k;
    }
    for (int i = 0; i < kPixels; ++i) {
      (i % 4 == 0 ? rare : calm).push_back(est[size_t(i)]);
    }
  }
  EXPECT_GT(aim_most, plan.aim) << "the aim rose";
  for (const auto& [v, mean] : {std::pair{calm, 1.0}, std::pair{rare, mu}}) {
    const st_test::Stats w = st_test::mean_se(v);
    EXPECT_LT(std::abs(w.mean - mean) / w.se, 4.0) << "weighted mean " << w.mean << " vs " << mean;
    EXPECT_GT(std::abs(1.03 * w.mean - mean) / w.se, 4.0) << "the twin: a 3% error must be seen (mean " << mean << ")";
  }
}

TEST(AdaptiveWeights, AreUnbiasedWhereAveragingAPixelsOwnStoppedSamplesIsNot) {
  const double mu = 0.98 * 1.0 + 0.02 * 40.0;
  AdaptivePlan plan;
  plan.target = 0.1;
  plan.spp = 1024;
  plan.pilot = 16;
  std::mt19937_64 rng(12345);
  const int kPixels = 100000;  // enough that a 3% error is well beyond 4 SE
  std::vector<double> weighted, averaged;
  int64_t samples = 0, min_n = plan.spp, max_n = 0;
  for (int t = 0; t < kPixels; ++t) {
    const PixelRun r = simulate_pixel(rng, plan);
    weighted.push_back(r.weighted);
    averaged.push_back(r.averaged);
    samples += r.n;
    min_n = std::min(min_n, r.n);
    max_n = std::max(max_n, r.n);
  }
  EXPECT_LT(min_n, max_n) << "the rule gives pixels different sample counts";
  EXPECT_LT(samples / kPixels, plan.spp);
  const st_test::Stats w = st_test::mean_se(weighted), a = st_test::mean_se(averaged);
  EXPECT_LT(std::abs(w.mean - mu) / w.se, 4.0) << "weighted mean " << w.mean << " vs " << mu;
  EXPECT_GT(std::abs(1.03 * w.mean - mu) / w.se, 4.0) << "the twin: a 3% error must be seen";
  EXPECT_GT(std::abs(a.mean - mu) / a.se, 4.0) << "the twin: averaging the stopped samples is biased (" << a.mean << ")";
}

AdaptiveResult render_adaptive_scene(const SceneDesc& scene, double target, int spp, bool guiding = false,
                                     double aim = kAdaptiveAim) {
  RenderOptions o = st_test::quiet_options(spp);
  o.noise_target = target;
  o.adaptive = true;
  if (guiding) {
    o.guiding = kGuidingOn;
    o.guide_grid_cells = 2;  // a small film trains few records: few, well-filled regions
    o.guide_alpha = kGuideAlpha;  // every fitted region guides, whatever the records say it pays
  }
  Renderer r(scene, o);
  AdaptivePlan plan;
  plan.target = target;
  plan.spp = spp;
  plan.aim = aim;
  return render_adaptive(r, plan);
}

// `f` agrees with a uniform 1024-spp render of another seed within 4 SE; a 3% error does not.
void expect_agrees_with_uniform_render(const SceneDesc& scene, const RenderResult& f) {
  RenderOptions o = st_test::quiet_options(1024);
  o.seed = 977;
  Renderer ref(scene, o);
  const RenderResult reference = ref.render();
  EXPECT_LT(st_test::max_z(f, reference), 4.0);
  EXPECT_GT(st_test::max_z(f, reference, 1.03), 4.0) << "the twin: a 3% error must be seen";
}

TEST(AdaptiveRender, ReachesItsTargetWithFewerSamplesAndAgreesWithAUniformRender) {
  const std::string dir = test_dir();
  const SceneDesc scene = st_test::scene_from_json(small_noise_scene(dir), dir);
  const AdaptiveResult a = render_adaptive_scene(scene, 0.04, 2048);
  const RenderResult& f = a.film;
  ASSERT_FALSE(f.interrupted);
  const NoiseEstimate e = estimate_film_noise(f.sum, f.aov_sum, f.aov_channels, f.spp_done);
  EXPECT_LE(e.error, 0.04);
  EXPECT_GT(e.pixels, 100u);
  EXPECT_TRUE(f.noise_target_reached);
  EXPECT_GT(a.rounds, 2);
  EXPECT_LT(a.mean_samples, 2048.0);
  float lo = 1e30f, hi = 0;
  for (float n : a.samples) lo = std::min(lo, n), hi = std::max(hi, n);
  EXPECT_LT(lo, hi) << "every pixel took the same samples";
  expect_agrees_with_uniform_render(scene, f);
  // the rounds are samples keyed by (pixel, sample) and decisions of the host: the same bits again
  const AdaptiveResult again = render_adaptive_scene(scene, 0.04, 2048);
  ASSERT_EQ(again.film.sum.size(), f.sum.size());
  for (size_t i = 0; i < f.sum.size(); ++i) ASSERT_EQ(again.film.sum[i], f.sum[i]) << "value " << i;
}

// A stop in the pilot leaves pixels of fewer than kNoiseMinSpp samples (most of them without a
// sample variance): the film's noise is not measured (a film whose pixels all have a variance of 0
// would read as noise 0%), and the round's end is the samples drawn, not the pilot's 16. The twin:
// the same render, not stopped, measures its noise after the pilot.
TEST(AdaptiveRender, AStopInThePilotLeavesTheNoiseUnmeasured) {
  const std::string dir = test_dir();
  const SceneDesc scene = st_test::scene_from_json(small_noise_scene(dir), dir);
  for (const bool stop_in_pilot : {true, false}) {
    SCOPED_TRACE(stop_in_pilot ? "stopped in the pilot" : "the twin: not stopped");
    std::atomic<bool> stop{false};
    RenderOptions o = st_test::quiet_options(64);
    o.noise_target = 0.5;
    o.adaptive = true;
    o.path_slots = 64;  // many batches in the pilot, so that a stop finds some finished
    o.batches_in_flight = 1;
    o.stop = &stop;
    if (stop_in_pilot) o.progress = [&](double f) { if (f > 0.15) stop = true; };
    Renderer r(scene, o);
    AdaptivePlan plan;
    plan.target = 0.5;
    plan.spp = 64;
    bool measured_seen = false;
    const AdaptiveResult a = render_adaptive(r, plan, [&](const AdaptiveResult& so_far) { measured_seen |= so_far.noise_measured; });
    EXPECT_EQ(a.noise_measured, !stop_in_pilot);
    EXPECT_EQ(measured_seen, !stop_in_pilot);
    EXPECT_EQ(a.film.interrupted, stop_in_pilot);
    const float least = *std::min_element(a.samples.begin(), a.samples.end());
    if (stop_in_pilot) {
      EXPECT_LT(least, float(kNoiseMinSpp));
      EXPECT_LT(a.round_end, kNoiseMinSpp);
      EXPECT_GT(a.round_end, 0);
    } else {
      EXPECT_GE(least, float(kNoiseMinSpp));
    }
  }
}

// A round renders as one list of entries (adaptive.cpp round_entries): a pixel listed twice with
// sample offsets 0 and 4 of a 4-spp render draws the very samples of an 8-spp render of it, and one
// listed once those of a 4-spp render; the twin lists a pixel twice at offset 0 (its first 4
// samples twice over), which must not match.
TEST(AdaptiveRender, AListOfEntriesDrawsEachEntrysOwnSamples) {
  const std::string dir = test_dir();
  const SceneDesc scene = st_test::scene_from_json(small_noise_scene(dir), dir);
  RenderOptions o = st_test::quiet_options(8);
  o.noise_target = 0.05;
  o.adaptive = true;
  Renderer r(scene, o);
  const uint32_t w = r.settings().window.width, h = r.settings().window.height;
  const uint32_t a = (h / 2) * w + w / 2, b = a + 1;
  const RenderResult eight = r.render_pixels({a}, 16, 8), four = r.render_pixels({b}, 16, 4);
  const RenderResult list = r.render_pixels({a, b, a}, 16, 4, {0, 0, 4});
  const RenderResult twin = r.render_pixels({a, b, a}, 16, 4, {0, 0, 0});
  const size_t na = eight.aov_channels.size();
  ASSERT_EQ(list.sum.size(), 9u);
  ASSERT_EQ(list.aov_sum.size(), 3 * na);
  auto near = [](double x, double y) { return std::abs(x - y) <= 1e-5 * std::max(std::abs(x), std::abs(y)) + 1e-9; };
  double differs = 0;
  for (int c = 0; c < 3; ++c) {
    ASSERT_GT(eight.sum[c], 0.0) << "the test pixel sees the medium";
    EXPECT_TRUE(near(list.sum[c] + list.sum[6 + c], eight.sum[c])) << c;
    EXPECT_TRUE(near(list.sum[3 + c], four.sum[c])) << c;
    differs += !near(twin.sum[c] + twin.sum[6 + c], eight.sum[c]);
  }
  for (size_t q = 0; q < na; ++q) {
    EXPECT_TRUE(near(list.aov_sum[q] + list.aov_sum[2 * na + q], eight.aov_sum[q])) << eight.aov_channels[q];
    EXPECT_TRUE(near(list.aov_sum[na + q], four.aov_sum[q])) << eight.aov_channels[q];
  }
  EXPECT_GT(differs, 0) << "the twin: the same samples twice must differ from 8 samples";
}

// With guiding, the training passes run in the pilot round and their samples are part of it: the
// adaptive estimate still agrees with a uniform unguided render (and a 3% error does not).
TEST(AdaptiveRender, WithGuidingTrainsInThePilotAndAgreesWithAUniformRender) {
  const std::string dir = test_dir();
  const SceneDesc scene = st_test::scene_from_json(small_noise_scene(dir), dir);
  const AdaptiveResult a = render_adaptive_scene(scene, 0.05, 1024, true);
  const RenderResult& f = a.film;
  ASSERT_FALSE(f.interrupted);
  EXPECT_TRUE(f.guide.used);
  EXPECT_EQ(f.guide.training_passes, kGuideTrainingPasses);
  EXPECT_GT(a.rounds, 1);
  expect_agrees_with_uniform_render(scene, f);
}

// A render that misses its target says why: every pixel finished at an aim above the target
// (pixels-finished, no pixel at the spp), or pixels ran to the spp (spp); one that meets it says
// nothing of the kind.
TEST(AdaptiveRender, RecordsWhyItMissedItsTarget) {
  const std::string dir = test_dir();
  const SceneDesc scene = st_test::scene_from_json(small_noise_scene(dir), dir);
  const AdaptiveResult above = render_adaptive_scene(scene, 0.04, 2048, false, 2.0);  // aimed at twice the target
  EXPECT_FALSE(above.film.noise_target_reached);
  EXPECT_FALSE(above.film.interrupted);
  EXPECT_LT(*std::max_element(above.samples.begin(), above.samples.end()), 2048.0f);
  EXPECT_EQ(above.stop_reason, "pixels-finished");
  const AdaptiveResult capped = render_adaptive_scene(scene, 0.001, 32);
  EXPECT_FALSE(capped.film.noise_target_reached);
  EXPECT_EQ(*std::max_element(capped.samples.begin(), capped.samples.end()), 32.0f);
  EXPECT_EQ(capped.stop_reason, "spp");
  const AdaptiveResult met = render_adaptive_scene(scene, 0.5, 2048);
  EXPECT_TRUE(met.film.noise_target_reached);
  EXPECT_EQ(met.stop_reason, "");
}

std::string meta_text(const std::string& path, const std::string& key) {
  auto in = OIIO::ImageInput::open(path);
  return in ? in->spec().get_string_attribute("spectrack:" + key, "<missing>") : "<unreadable>";
}

TEST(CliAdaptive, WritesTheSamplesLayerAndRefusesWhatCannotWork) {
  const std::string dir = test_dir();
  const std::string scene = write_scene(dir, "scene.json", small_noise_scene(dir));
  RunOptions ro;
  ro.timeout_s = 240;
  Proc p = run({"render", scene, "-o", dir + "/a.exr", "--noise-target", "0.06", "--spp", "512", "--adaptive",
                "--stats-json", dir + "/a.json"}, ro);
  ASSERT_TRUE(p.exited && p.code == 0) << p.describe();
  EXPECT_THAT(p.out, HasSubstr("adaptive"));
  auto in = OIIO::ImageInput::open(dir + "/a.exr");
  ASSERT_TRUE(in);
  const auto& names = in->spec().channelnames;
  EXPECT_NE(std::find(names.begin(), names.end(), "samples"), names.end());
  EXPECT_NE(std::find(names.begin(), names.end(), "variance.R"), names.end());
  EXPECT_EQ(in->spec().get_int_attribute("spectrack:adaptive", 0), 1);
  EXPECT_GT(in->spec().get_float_attribute("spectrack:adaptive_mean_spp", 0.0f), 16.0f);
  EXPECT_LT(in->spec().get_float_attribute("spectrack:adaptive_mean_spp", 1e9f), 512.0f);
  EXPECT_EQ(meta_text(dir + "/a.exr", "stop_reason"), "noise-target");
  {  // the statistics count samples per pixel as a uniform render's do: the mean, rounded
    const json j = json::parse(std::ifstream(dir + "/a.json"));
    EXPECT_EQ(j["samples_per_device"], json::array({std::llround(j["adaptive_mean_spp"].get<double>())})) << j.dump();
  }
  // a target out of reach at the spp: the metadata, the statistics and the summary line say so
  p = run({"render", scene, "-o", dir + "/s.exr", "--noise-target", "0.001", "--spp", "32", "--adaptive",
           "--stats-json", dir + "/s.json"}, ro);
  ASSERT_TRUE(p.exited && p.code == 0) << p.describe();
  EXPECT_THAT(p.out, HasSubstr("noise target missed at --spp"));
  EXPECT_EQ(meta_text(dir + "/s.exr", "stop_reason"), "spp");
  EXPECT_EQ(json::parse(std::ifstream(dir + "/s.json")).value("stop_reason", ""), "spp");
  // an adaptive film merges with nothing: its pixels have sample counts of their own
  p = run({"merge", dir + "/m.exr", dir + "/a.exr"});
  EXPECT_EQ(p.code, 2) << p.describe();
  EXPECT_THAT(p.out, HasSubstr("adaptive"));
  // refusals: no noise target, shards, tiles, several devices, checkpoints: exit 2
  for (std::vector<std::string> extra :
       {std::vector<std::string>{}, {"--noise-target", "0.05", "--spp-range", "0:8"},
        {"--noise-target", "0.05", "--pixel-bounds", "0,8,0,8"}, {"--noise-target", "0.05", "--device", "0:0,0:0"},
        {"--noise-target", "0.05", "--checkpoint", "5"}}) {
    std::vector<std::string> args = {"render", scene, "-o", dir + "/r.exr", "--adaptive", "--quiet"};
    args.insert(args.end(), extra.begin(), extra.end());
    p = run(args);
    EXPECT_EQ(p.code, 2) << p.describe();
  }
  // the scene field, type-checked with its path
  json bad = small_noise_scene(dir);
  bad["render"]["adaptive"] = "yes";
  p = run({"render", write_scene(dir, "bad.json", bad), "-o", dir + "/b.exr", "--quiet"});
  EXPECT_EQ(p.code, 1) << p.describe();
  EXPECT_THAT(p.out, HasSubstr("/render/adaptive"));
}

}  // namespace
