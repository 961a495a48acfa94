// phase_models.h: the scene's phase functions and the one kernel form of the extended set.
//
// Design: the kernels know isotropic, Henyey-Greenstein and one blend of two Draine lobes,
//   f = (1 - w) D(g1, alpha1) + w D(g2, alpha2),
//   D(g, alpha) = HG(g) (1 + alpha cos^2) / (1 + alpha (1 + 2 g^2) / 3)   (Draine 2003),
// (kernels/phase.h). Every other scene phase is a blend: "draine" one lobe, "rayleigh" the lobe
// g = 0, alpha = 1 (3 / (16 pi) (1 + cos^2)), "hg2" two lobes with alpha = 0, and "mie" the
// approximate Mie phase function of Jendersie and d'Eon 2023 (SIGGRAPH Talks, "An Approximate Mie
// Scattering Function for Fog and Cloud Rendering"): an HG lobe (g_HG) and a Draine lobe (g_D,
// alpha) of weight w_D, fitted to Lorenz-Mie theory for water droplets in air over visible
// wavelengths, as functions of the droplet diameter d in micrometres. Their fit for
// 5 um <= d <= 50 um (the talk's equations) is the one used; other diameters are refused. None of
// these shapes depends on the wavelength (the fit averages over the visible range), so RGB and
// spectral mode share them.
#pragma once
#include <string>

namespace spectrack {

struct PhaseDesc;

constexpr double kMieMinDiameterUm = 5.0;
constexpr double kMieMaxDiameterUm = 50.0;

// The fitted blend parameters of the approximate Mie phase function for diameter d (um).
struct MieFit {
  double g_hg, g_d, alpha, w_d;
};
MieFit mie_fit(double diameter_um);

// The kernel's Draine blend for a scene phase: "draine" (g, alpha), "rayleigh", "hg2" (g1, g2, w)
// and "mie" (diameter_um); sets type, g and the blend's (alpha1, g2, alpha2, w).
PhaseDesc draine_phase(double g, double alpha);
PhaseDesc rayleigh_phase();
PhaseDesc hg2_phase(double g1, double g2, double w);
PhaseDesc mie_phase(double diameter_um);

// Draine's D(g, alpha) at cos theta, and its mean cosine g (1 + alpha (3 + 2 g^2) / 5) / (1 + alpha (1 + 2 g^2) / 3).
double draine_value(double g, double alpha, double cos_theta);
double draine_mean_cos(double g, double alpha);

// The largest value of the phase function over all directions (1 / (4 pi) for isotropic), with the
// g's as the kernels hold them (float).
double phase_peak(const PhaseDesc& p);

}  // namespace spectrack
