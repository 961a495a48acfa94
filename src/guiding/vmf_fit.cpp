// vmf_fit.cpp: the weighted EM fit of a von Mises-Fisher mixture (vmf_fit.h): weighted k-means++
// initialisation, log-domain E steps, MAP M steps with kappa from the inverted mean resultant
// length. Double precision throughout; the result is rounded to the float record once, at the end.
#include "guiding/vmf_fit.h"

#include <algorithm>
#include <array>
#include <cmath>

namespace spectrack {

namespace {

constexpr double kPi = 3.14159265358979323846;

struct Lobe {
  std::array<double, 3> mu{0, 0, 1};
  double kappa = 0, weight = 0;
};

// splitmix64: a fixed, platform-independent generator for the initialisation.
struct SplitMix {
  uint64_t s;
  uint64_t next() {
    uint64_t z = (s += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  double uniform() { return double(next() >> 11) * (1.0 / 9007199254740992.0); }
};

double dot3(const float* a, const std::array<double, 3>& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

// log of kappa / (2 pi (1 - exp(-2 kappa))), the lobe's density at its mean.
double log_norm(double kappa) {
  if (kappa <= 1e-12) return -std::log(4 * kPi);
  return std::log(kappa) - std::log(2 * kPi) - std::log(-std::expm1(-2 * kappa));
}

// d/dkappa (coth kappa - 1/kappa) = 1/kappa^2 - 1/sinh^2 kappa.
double mean_cosine_slope(double kappa) {
  if (kappa < 1e-3) return 1.0 / 3.0 - kappa * kappa / 15.0;
  if (kappa > 40) return 1.0 / (kappa * kappa);
  double s = std::sinh(kappa);
  return 1.0 / (kappa * kappa) - 1.0 / (s * s);
}

// Weighted k-means++ on the sphere: the first mean drawn in proportion to the weights, each next
// one in proportion to weight x (1 - cos to the nearest mean chosen so far).
std::vector<Lobe> initial_lobes(const std::vector<DirectionalSample>& xs, const std::vector<double>& s, int K,
                                const VmfFitOptions& o) {
  SplitMix rng{o.seed};
  std::vector<Lobe> lobes;
  std::vector<double> dist(xs.size(), 1.0);  // weight factor: uniform before the first mean
  for (int k = 0; k < K; ++k) {
    double total = 0;
    for (size_t i = 0; i < xs.size(); ++i) total += s[i] * dist[i];
    bool by_weight = !(total > 0);  // every sample sits on a mean already: draw by weight alone
    if (by_weight)
      for (size_t i = 0; i < xs.size(); ++i) total += s[i];
    double target = rng.uniform() * total, cdf = 0;
    size_t pick = xs.size() - 1;
    for (size_t i = 0; i < xs.size(); ++i) {
      cdf += s[i] * (by_weight ? 1.0 : dist[i]);
      if (target < cdf) {
        pick = i;
        break;
      }
    }
    Lobe l;
    l.mu = {xs[pick].dir[0], xs[pick].dir[1], xs[pick].dir[2]};
    double len = std::sqrt(l.mu[0] * l.mu[0] + l.mu[1] * l.mu[1] + l.mu[2] * l.mu[2]);
    for (double& c : l.mu) c /= len;
    l.kappa = o.kappa_init;
    l.weight = 1.0 / K;
    lobes.push_back(l);
    for (size_t i = 0; i < xs.size(); ++i) dist[i] = std::min(dist[i], std::max(0.0, 1.0 - dot3(xs[i].dir, l.mu)));
  }
  return lobes;
}

struct Moments {
  std::vector<double> W;                   // sum of s_i r_ik
  std::vector<std::array<double, 3>> R;    // sum of s_i r_ik x_i
  double log_likelihood = 0;               // sum of s_i log p(x_i)
};

// The E step and the sums the M step needs, in sample order.
Moments expectation(const std::vector<DirectionalSample>& xs, const std::vector<double>& s,
                    const std::vector<Lobe>& lobes) {
  const size_t K = lobes.size();
  Moments m{std::vector<double>(K, 0.0), std::vector<std::array<double, 3>>(K, {0, 0, 0}), 0};
  std::vector<double> base(K), lp(K);
  for (size_t k = 0; k < K; ++k) base[k] = std::log(lobes[k].weight) + log_norm(lobes[k].kappa);
  for (size_t i = 0; i < xs.size(); ++i) {
    if (!(s[i] > 0)) continue;
    double top = -INFINITY;
    for (size_t k = 0; k < K; ++k) {
      lp[k] = base[k] + lobes[k].kappa * (dot3(xs[i].dir, lobes[k].mu) - 1.0);
      top = std::max(top, lp[k]);
    }
    double sum = 0;
    for (size_t k = 0; k < K; ++k) sum += (lp[k] = std::exp(lp[k] - top));
    m.log_likelihood += s[i] * (top + std::log(sum));
    for (size_t k = 0; k < K; ++k) {
      double r = s[i] * lp[k] / sum;
      m.W[k] += r;
      for (int a = 0; a < 3; ++a) m.R[k][a] += r * xs[i].dir[a];
    }
  }
  return m;
}

// The MAP M step: weights with a Dirichlet pseudo-count, means, kappa from the mean resultant
// length pulled toward the prior mean cosine.
void maximisation(const Moments& m, double total, const VmfFitOptions& o, std::vector<Lobe>& lobes) {
  const double K = double(lobes.size());
  for (size_t k = 0; k < lobes.size(); ++k) {
    Lobe& l = lobes[k];
    l.weight = (m.W[k] + o.weight_prior) / (total + K * o.weight_prior);
    const auto& R = m.R[k];
    double len = std::sqrt(R[0] * R[0] + R[1] * R[1] + R[2] * R[2]);
    if (len > 0)
      for (int a = 0; a < 3; ++a) l.mu[a] = R[a] / len;
    double rbar = (len + o.mean_cosine_strength * o.mean_cosine_prior) / (m.W[k] + o.mean_cosine_strength);
    l.kappa = std::min(vmf_kappa_from_mean_cosine(rbar), o.kappa_max);
  }
}

st_vmf_mixture to_record(const std::vector<Lobe>& lobes) {
  st_vmf_mixture out{};
  for (int k = 0; k < ST_VMF_LOBES; ++k) out.lobe[k] = st_float4{0.0f, 0.0f, 1.0f, 0.0f};
  for (size_t k = 0; k < lobes.size(); ++k) {
    const Lobe& l = lobes[k];
    out.lobe[k] = st_float4{float(l.mu[0]), float(l.mu[1]), float(l.mu[2]), float(l.kappa)};
    out.weight[k] = float(l.weight);
  }
  return out;
}

}  // namespace

double vmf_mean_cosine(double kappa) {
  if (kappa < 1e-3) return kappa / 3.0 - kappa * kappa * kappa / 45.0;
  return 1.0 / std::tanh(kappa) - 1.0 / kappa;
}

double vmf_kappa_from_mean_cosine(double r) {
  if (!(r > 0)) return 0.0;
  if (r >= 1) return INFINITY;
  double kappa = r * (3.0 - r * r) / (1.0 - r * r);  // Banerjee et al. 2005, for the sphere
  for (int i = 0; i < 8; ++i) {  // Newton on coth kappa - 1/kappa = r (increasing, concave)
    double step = (vmf_mean_cosine(kappa) - r) / mean_cosine_slope(kappa);
    double next = kappa - step;
    if (!(next > 0)) next = 0.5 * kappa;
    bool done = std::fabs(next - kappa) <= 1e-12 * kappa;
    kappa = next;
    if (done) break;
  }
  return kappa;
}

VmfFitResult fit_vmf_mixture(const std::vector<DirectionalSample>& samples, const VmfFitOptions& o) {
  VmfFitResult res;
  res.mixture = to_record({});
  double sum_w = 0, sum_w2 = 0;
  for (const auto& x : samples) {
    double w = std::max(0.0, double(x.weight));
    sum_w += w;
    sum_w2 += w * w;
  }
  if (!(sum_w > 0)) return res;
  // weights rescaled to sum to the effective sample count, the unit the priors are counted in
  res.effective_samples = sum_w * sum_w / sum_w2;
  std::vector<double> s(samples.size());
  for (size_t i = 0; i < samples.size(); ++i)
    s[i] = std::max(0.0, double(samples[i].weight)) * (res.effective_samples / sum_w);
  const int K = std::clamp(o.lobes, 1, ST_VMF_LOBES);
  std::vector<Lobe> lobes = initial_lobes(samples, s, K, o);
  double previous = -INFINITY;
  for (res.iterations = 0; res.iterations < o.max_iterations; ++res.iterations) {
    Moments m = expectation(samples, s, lobes);
    double ll = m.log_likelihood / res.effective_samples;
    maximisation(m, res.effective_samples, o, lobes);
    bool converged = std::fabs(ll - previous) < o.tolerance * std::max(1.0, std::fabs(ll));
    previous = ll;
    if (converged) break;
  }
  res.log_likelihood = previous;
  res.mixture = to_record(lobes);
  return res;
}

}  // namespace spectrack
