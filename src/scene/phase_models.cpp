// phase_models.cpp: the extended phase set as Draine blends, and the approximate Mie fit
// (phase_models.h has the design).
#include "scene/phase_models.h"

#include <algorithm>
#include <cmath>

#include "scene/scene.h"

namespace spectrack {
namespace {
constexpr double kPi = 3.14159265358979323846;

PhaseDesc blend(double g1, double alpha1, double g2, double alpha2, double w) {
  PhaseDesc p;
  p.type = ST_PHASE_DRAINE_BLEND;
  p.g = g1;
  p.blend = {alpha1, g2, alpha2, w};
  return p;
}

double hg_peak(double g) {
  const double a = std::abs(double(float(g)));
  return (1.0 + a) / (4.0 * kPi * (1.0 - a) * (1.0 - a));
}

// HG's largest value times the largest (1 + alpha cos^2) / normaliser (at cos = +-1).
double draine_peak(double g, double alpha) {
  return hg_peak(g) * (1.0 + alpha) / (1.0 + alpha * (1.0 + 2.0 * g * g) / 3.0);
}
}  // namespace

// Jendersie and d'Eon 2023, the fit for 5 um <= d <= 50 um.
MieFit mie_fit(double d) {
  MieFit f;
  f.g_hg = std::exp(-0.0990567 / (d - 1.67154));
  f.g_d = std::exp(-2.20679 / (d + 3.91029) - 0.428934);
  f.alpha = std::exp(3.62489 - 8.29288 / (d + 5.52825));
  f.w_d = std::exp(-0.599085 / (d - 0.641583) - 0.665888);
  return f;
}

PhaseDesc draine_phase(double g, double alpha) { return blend(g, alpha, 0.0, 0.0, 0.0); }
PhaseDesc rayleigh_phase() { return blend(0.0, 1.0, 0.0, 0.0, 0.0); }
PhaseDesc hg2_phase(double g1, double g2, double w) { return blend(g1, 0.0, g2, 0.0, w); }
PhaseDesc mie_phase(double diameter_um) {
  const MieFit f = mie_fit(diameter_um);
  return blend(f.g_hg, 0.0, f.g_d, f.alpha, f.w_d);
}

double draine_value(double g, double alpha, double c) {
  const double hg = (1.0 - g * g) / (4.0 * kPi * std::pow(1.0 + g * g - 2.0 * g * c, 1.5));
  return hg * (1.0 + alpha * c * c) / (1.0 + alpha * (1.0 + 2.0 * g * g) / 3.0);
}

double draine_mean_cos(double g, double alpha) {
  return g * (1.0 + alpha * (3.0 + 2.0 * g * g) / 5.0) / (1.0 + alpha * (1.0 + 2.0 * g * g) / 3.0);
}

double phase_peak(const PhaseDesc& p) {
  if (p.type == ST_PHASE_HG) return hg_peak(p.g);
  if (p.type != ST_PHASE_DRAINE_BLEND) return 1.0 / (4.0 * kPi);
  return (1.0 - p.blend[3]) * draine_peak(p.g, p.blend[0]) + p.blend[3] * draine_peak(p.blend[1], p.blend[2]);
}

}  // namespace spectrack
