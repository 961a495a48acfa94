// adaptive.cpp: the rules that decide an adaptive render's rounds (adaptive.h: the weights, the
// lengths, the cap, the aim, the pilot's weights); adaptive_render.cpp renders the rounds.
#include "integrator/adaptive.h"

#include <algorithm>
#include <limits>
#include <map>
#include <cmath>
#include <numeric>

#include "integrator/noise.h"

namespace spectrack {

double AdaptivePixel::sample_variance(int c) const {
  if (n < 2) return 0.0;
  const double dn = double(n);
  return std::max(0.0, (s2[c] - s1[c] * s1[c] / dn) / (dn - 1.0));
}

double AdaptivePixel::brightness() const { return n > 0 ? (s1[0] + s1[1] + s1[2]) / (3.0 * double(n)) : 0.0; }

// Every round but a pixel's last starts and ends on a block of stratified wavelengths (types.h
// ST_WAVELENGTH_BLOCK): the pilot and every round's full length are multiples of it, so a round's
// wavelengths share no block with the samples its weight was decided from (docs/adaptive.md).
static_assert(kNoiseMinSpp % ST_WAVELENGTH_BLOCK == 0 && kAdaptiveLastRoundSteps % ST_WAVELENGTH_BLOCK == 0,
              "adaptive rounds start on a block of stratified wavelengths");

int64_t adaptive_round_samples(int64_t n, const AdaptivePlan& plan) {
  const int64_t pilot = std::min(plan.pilot, plan.spp);
  if (n == 0) return pilot;
  // a multiple of kAdaptiveLastRoundSteps, so that every length of the round is a multiple of its
  // quarter (one render of entries: round_entries)
  const int64_t k = (std::max(pilot, n / 2) + kAdaptiveLastRoundSteps - 1) / kAdaptiveLastRoundSteps * kAdaptiveLastRoundSteps;
  return std::min(k, plan.spp - n);
}

double adaptive_relative_variance(const AdaptivePixel& px, double floor) {
  const double sigma2 = (px.sample_variance(0) + px.sample_variance(1) + px.sample_variance(2)) / 3.0;
  const double m = std::max(px.brightness(), floor);
  return sigma2 > 0.0 && m > 0.0 ? sigma2 / (m * m) : 0.0;
}

std::vector<double> adaptive_neighbourhood(const std::vector<AdaptivePixel>& px, int width, int height, double floor) {
  std::vector<double> rho(px.size()), out(px.size(), 0.0);
  for (size_t i = 0; i < px.size(); ++i) rho[i] = adaptive_relative_variance(px[i], floor);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      double sum = 0;
      int count = 0;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int u = x + dx, v = y + dy;
          if (u >= 0 && v >= 0 && u < width && v < height) {
            sum += rho[size_t(v) * size_t(width) + size_t(u)];
            ++count;
          }
        }
      const size_t i = size_t(y) * size_t(width) + size_t(x);
      out[i] = std::max(rho[i], sum / double(count));
    }
  return out;
}

namespace {
// The samples to come that bring rho (V + B^2 / T) down to e^2 (inf: out of reach).
double samples_to_reach(const AdaptivePixel& px, double rho, double e) {
  if (!(e * e > rho * px.V)) return std::numeric_limits<double>::infinity();
  return std::ceil(px.B * px.B * rho / (e * e - rho * px.V));
}
}  // namespace

double adaptive_samples_needed(const AdaptivePixel& px, double rho, const AdaptivePlan& plan) {
  if (!(rho > 0.0)) return 0.0;  // nothing to average out (a background every sample sees alike)
  const double T = samples_to_reach(px, rho, plan.target * plan.aim);
  if (std::isfinite(T) || px.n == 0) return T;
  // the aim is out of reach: the target itself, else the samples whose share of the weight left
  // adds no more variance than the rounds so far hold (B^2 / T = V): the pixel ends within sqrt(2)
  // of the least error it can reach, sqrt(rho V), without running to the spp for the last bit
  const double T_target = samples_to_reach(px, rho, plan.target);
  if (std::isfinite(T_target)) return T_target;
  return px.V > 0.0 ? std::ceil(px.B * px.B / px.V) : 0.0;
}

double adaptive_round_weight(const AdaptivePixel& px, int64_t k, int64_t cap, double rho, const AdaptivePlan& plan) {
  // the pilot: fixed before any sample, as if every pixel took the whole spp
  if (px.n == 0) return k >= plan.spp ? 1.0 : double(k) / double(plan.spp);
  const int64_t left = std::min(cap, plan.spp) - px.n;
  if (k >= left) return px.B;
  // the samples to come that bring rho (V + B^2 / T) down to the aim, at most what is left
  const double T = std::min(double(left), adaptive_samples_needed(px, rho, plan));
  if (T <= double(k)) return px.B;
  // the weight from rho made larger where it rests on few samples (adaptive.h kAdaptiveWeightMargin)
  const double rho_w = rho * (1.0 + kAdaptiveWeightMargin / std::sqrt(double(px.n)));
  const double T_w = std::min(double(left), adaptive_samples_needed(px, rho_w, plan));
  return px.B * double(k) / std::max(T, T_w);
}

int64_t adaptive_round_length(const AdaptivePixel& px, int64_t k, int64_t cap, double rho, const AdaptivePlan& plan) {
  if (px.n == 0) return k;  // the pilot
  // the last round: the samples still needed (at most those left below the cap) rounded up to a
  // multiple of a quarter of the round, at least a quarter (a cap that fell below the pixel's
  // samples leaves none, and the weight left still needs samples)
  const int64_t q = (k + kAdaptiveLastRoundSteps - 1) / kAdaptiveLastRoundSteps;
  const int64_t left = std::min(cap, plan.spp) - px.n;
  const double T = std::min(double(left), adaptive_samples_needed(px, rho, plan));
  if (k < left && T > double(k)) return k;  // not the last round
  return std::min(k, std::max<int64_t>(q, (int64_t(std::ceil(T)) + q - 1) / q * q));
}

int64_t adaptive_cap(const std::vector<AdaptivePixel>& px, const std::vector<double>& rho, const AdaptivePlan& plan) {
  std::vector<double> need;
  for (size_t i = 0; i < px.size(); ++i) {
    const AdaptivePixel& x = px[i];
    if (!(x.brightness() > 0.0 && adaptive_relative_variance(x, 0.0) > 0.0)) continue;  // noise.h's counted pixels
    need.push_back(x.done() ? double(x.n) : double(x.n) + adaptive_samples_needed(x, rho[i], plan));
  }
  if (need.empty()) return plan.spp;
  auto rank = [&](double percentile) {  // nearest rank
    const size_t k = std::min(need.size() - 1, size_t(std::ceil(percentile * double(need.size()))) - 1);
    std::nth_element(need.begin(), need.begin() + std::ptrdiff_t(k), need.end());
    return need[k];
  };
  const double image = rank(kNoisePercentile);
  const double cap = std::min(rank(1.0 - (1.0 - kNoisePercentile) * plan.cap_share), kAdaptiveCapGrowth * image);
  return int64_t(std::min(double(plan.spp), std::max(cap, double(2 * plan.pilot))));
}


double adaptive_final_error(const AdaptivePixel& px, double rho, int64_t cap, const AdaptivePlan& plan) {
  const double left = double(std::min(cap, plan.spp) - px.n);
  const double T = std::max(1.0, std::min(left, adaptive_samples_needed(px, rho, plan)));
  return std::sqrt(rho * (px.V + px.B * px.B / T));
}

AdaptivePlan adaptive_aim(const std::vector<AdaptivePixel>& px, const std::vector<double>& rho, double floor,
                          const AdaptivePlan& plan) {
  // the drifts of the pixels that finished at an aim, log(measured / predicted error) times the
  // square root of the samples the prediction rested on (its spread falls as 1 / sqrt(n))
  std::vector<double> drift;
  std::vector<size_t> active;
  double counted = 0, above = 0;
  for (size_t i = 0; i < px.size(); ++i) {
    const AdaptivePixel& x = px[i];
    if (!(x.brightness() > 0.0 && adaptive_relative_variance(x, 0.0) > 0.0)) continue;  // noise.h's counted pixels
    ++counted;
    if (!x.done()) {
      active.push_back(i);
      continue;
    }
    const double measured = std::sqrt(adaptive_relative_variance(x, floor) * x.V);
    if (measured > plan.target) ++above;
    if (x.predicted >= kAdaptiveDriftFrom * plan.aim * plan.target && x.predicted <= plan.target && x.decided > 0)
      drift.push_back(std::log(measured / x.predicted) * std::sqrt(double(x.decided)));
  }
  if (drift.size() < kAdaptiveDriftMin) return plan;
  // the allowance (noise.h's percentile) less the finished pixels above the target
  const double budget = counted - std::ceil(kNoisePercentile * counted) - above;
  std::sort(drift.begin(), drift.end());
  // the aim and the cap's share that fit and leave the active pixels the fewest samples to take
  AdaptivePlan best = plan;
  double fewest = std::numeric_limits<double>::infinity();
  const int steps = int(std::floor((1.0 - plan.aim) / kAdaptiveAimStep + 1e-9));
  for (int i = 0; i < steps; ++i)
    for (int j = 0; j < kAdaptiveCapShares; ++j) {
      AdaptivePlan at = plan;
      at.aim = 1.0 - double(i) * kAdaptiveAimStep;
      at.cap_share = kAdaptiveCapShare + double(j) * kAdaptiveCapShareStep;
      const int64_t cap = adaptive_cap(px, rho, at);
      // each active pixel ends above the target with the share of the drifts that would carry its
      // predicted error there, scaled to its samples (the cap's pixels included: those it stops far
      // above the target count whole, those it leaves just below count as the others)
      double expected = 0, variance = 0, samples = 0;
      for (const size_t p : active) {
        const AdaptivePixel& x = px[p];
        const double e = adaptive_final_error(x, rho[p], cap, at);
        const double from = std::log(plan.target / e) * std::sqrt(double(x.n));
        const double p_above = double(drift.end() - std::upper_bound(drift.begin(), drift.end(), from)) / double(drift.size());
        expected += p_above;
        variance += p_above * (1.0 - p_above);
        samples += std::max(0.0, std::min(double(std::min(cap, plan.spp) - x.n), adaptive_samples_needed(x, rho[p], at)));
      }
      if (expected + kAdaptiveDriftSpread * std::sqrt(variance) <= budget && samples < fewest) {
        fewest = samples;
        best = at;
      }
    }
  return best;
}

std::vector<double> adaptive_pilot_weights(const std::vector<AdaptivePixel>& pilot, int width, int height,
                                           const AdaptivePlan& plan) {
  const double k0 = double(std::min(plan.pilot, plan.spp)), spp = double(plan.spp);
  const double e = plan.target * plan.aim;
  std::vector<double> need(pilot.size()), out(pilot.size(), k0 / spp);
  // the samples of a uniform estimate at the aim, from the pixel's own brightness (no floor: the
  // floor comes from every pilot)
  for (size_t i = 0; i < pilot.size(); ++i) need[i] = adaptive_relative_variance(pilot[i], 0.0) / (e * e);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      double most = 0;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int u = x + dx, v = y + dy;
          if ((dx || dy) && u >= 0 && v >= 0 && u < width && v < height)
            most = std::max(most, need[size_t(v) * size_t(width) + size_t(u)]);
        }
      if (most > 0.0)
        out[size_t(y) * size_t(width) + size_t(x)] = k0 / std::min(spp, std::max(kAdaptivePilotMargin * most, kAdaptivePilotMin * k0));
    }
  return out;
}

void adaptive_add_round(AdaptivePixel& px, double a, int64_t k, const double* s1, const double* s2) {
  px.n += k;
  for (int c = 0; c < 3; ++c) {
    px.s1[c] += s1[c];
    px.s2[c] += s2[c];
  }
  px.V += a * a / double(k);
  px.B = a >= px.B ? 0.0 : px.B - a;
}

}  // namespace spectrack
