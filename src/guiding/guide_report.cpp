// guide_report.cpp: what a fitted guide cache would do to a path, printed for measurements
// (SPECTRACK_GUIDE_REPORT=1, docs/guiding.md "A well-trained cache").
//
// Design: the one-sample mixture's weight W = f_phase / p_mix has E[W] = 1 under the mixture for
// every guide, and a second moment M2 = E[W^2] = integral of f_phase^2 / p_mix >= 1 (Cauchy-Schwarz),
// 1 only where p_mix = f_phase. Where the incident radiance does not vary with the direction (deep
// in a dense medium), guiding cannot remove variance, and a path's weight after n guided events has
// a second moment of about M2^n: the factor that a long random walk compounds. The report estimates
// M2 per guided region by Monte Carlo over propagation directions wo (uniform on the sphere: deep
// vertices see every direction) and phase-sampled directions (M2 = E_f[f / p_mix]), with the
// device's own density functions (kernels/guiding.h), and prints the regions' mean (weighted by
// their records) and the lobes of the most crowded regions with their cosine to the sun.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <random>

#include "guiding/guide_cache.h"

namespace spectrack {

namespace {

double hg_eval(double g, double c) {
  const double d = 1 + g * g - 2 * g * c;
  return (1 - g * g) / (4 * M_PI * d * std::sqrt(d));
}

// A Henyey-Greenstein direction around wo.
st_vec3 hg_sample(float g, st_vec3 wo, double u1, double u2) {
  double c = 1 - 2 * u1;
  if (std::fabs(g) > 1e-3) {
    const double s = (1 - g * g) / (1 - g + 2 * g * u1);
    c = (1 + g * g - s * s) / (2 * g);
  }
  c = std::clamp(c, -1.0, 1.0);
  const double sn = std::sqrt(std::max(0.0, 1 - c * c)), phi = 2 * M_PI * u2;
  st_vec3 t, b;
  vmf_frame(wo, &t, &b);
  const double x = sn * std::cos(phi), y = sn * std::sin(phi);
  return vec3_make(float(x * t.x + y * b.x + c * wo.x), float(x * t.y + y * b.y + c * wo.y),
                   float(x * t.z + y * b.z + c * wo.z));
}

// M2 of region g's one-sample mixture for a phase function of asymmetry `hg`.
double second_moment(const st_guide_region& r, float hg, bool product, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const float kp = product ? vmf_phase_kappa(hg) : 0.0f;
  double sum = 0;
  const int n_wo = 16, n_w = 32;
  for (int i = 0; i < n_wo; ++i) {
    const st_vec3 wo = vmf_sample(vec3_make(0, 0, 1), 0.0f, float(u(rng)), float(u(rng)));
    const st_vec3 nu = hg >= 0 ? wo : vec3_make(-wo.x, -wo.y, -wo.z);
    for (int j = 0; j < n_w; ++j) {
      const st_vec3 w = hg_sample(hg, wo, u(rng), u(rng));
      const double f = hg_eval(hg, double(w.x) * wo.x + double(w.y) * wo.y + double(w.z) * wo.z);
      sum += f / guide_mixture_pdf(r.alpha, guide_pdf(&r.mix, nu, kp, w), float(f));
    }
  }
  return sum / (n_wo * n_w);
}

}  // namespace

void report_guide_cache(const GuideCache& c, float hg, bool product, const float* sun, int pass) {
  std::mt19937_64 rng(7);
  double m2 = 0, weight = 0, worst = 0;
  std::vector<int> guided;
  for (size_t i = 0; i < c.regions.size(); ++i) {
    const st_guide_region& r = c.regions[i];
    if (!(r.alpha > 0)) continue;
    guided.push_back(int(i));
    const double m = second_moment(r, hg, product, rng);
    m2 += m * r.records, weight += r.records, worst = std::max(worst, m);
  }
  double alpha = 0;
  for (int i : guided) alpha += c.regions[size_t(i)].alpha;
  std::fprintf(stderr, "# guide report, pass %d: %zu guided regions of %zu (mean alpha %.3f), phase g %.2f, product %d; "
               "M2 = E[(f/p_mix)^2] per event, mean over regions by records %.4f, worst %.4f; "
               "radiance records outside the grid %zu\n",
               pass, guided.size(), c.regions.size(), guided.empty() ? 0.0 : alpha / double(guided.size()), hg,
               int(product), weight > 0 ? m2 / weight : 0.0, worst, c.records_outside);
  std::sort(guided.begin(), guided.end(), [&](int a, int b) { return c.regions[a].records > c.regions[b].records; });
  for (size_t k = 0; k < guided.size() && k < 4; ++k) {
    const st_guide_region& r = c.regions[guided[k]];
    std::fprintf(stderr, "#   region %d: %g records, mean weight %g, alpha %.1f, lobes (weight kappa cos-to-sun [mean]):",
                 guided[k], r.records, r.weight, r.alpha);
    int order[ST_VMF_LOBES];
    std::iota(order, order + ST_VMF_LOBES, 0);
    std::sort(order, order + ST_VMF_LOBES, [&](int a, int b) { return r.mix.weight[a] > r.mix.weight[b]; });
    for (int j : order) {
      if (!(r.mix.weight[j] > 0.01f)) continue;
      const st_float4& l = r.mix.lobe[j];
      const double cs = sun ? l.x * sun[0] + l.y * sun[1] + l.z * sun[2] : 0.0;
      std::fprintf(stderr, " (%.2f %.1f %+.2f [%+.2f %+.2f %+.2f])", r.mix.weight[j], l.w, cs, l.x, l.y, l.z);
    }
    std::fprintf(stderr, "\n");
  }
}

}  // namespace spectrack
