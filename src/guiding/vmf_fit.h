// vmf_fit.h: the host's weighted EM fit of a von Mises-Fisher mixture (kernels/guiding.h) to
// weighted directional samples: the step that turns a region's radiance records into its guide.
//
// Design: expectation-maximisation on weighted samples (a record's direction and its weight, the
// luminance of the radiance it carried divided by the density it was drawn with). The E step
// works in the log domain in double precision (lobes of kappa 1e4 underflow any plain sum); the M
// step takes each lobe's weighted mean direction, its mean resultant length and kappa by
// Banerjee's approximation refined by Newton steps on the sphere's exact A(kappa) = coth kappa -
// 1/kappa. Maximum a posteriori priors keep a fit from few samples sane: the mean resultant length
// is pulled toward a prior mean cosine by a few pseudo-samples, counted against the samples'
// effective number (Kish), so a lobe of one heavy record stays broad; the weights get a Dirichlet
// pseudo-count. Lobes start from a weighted k-means++ choice with a fixed-seed generator. Every sum
// runs in sample order on one thread, so a fit is a pure function of (samples, options): the same
// input gives the same bits, which the renderer's determinism rule needs (docs/guiding.md).
#pragma once
#include <cstdint>
#include <vector>

#include "kernels/guiding.h"

namespace spectrack {

struct DirectionalSample {
  float dir[3];  // unit direction
  float weight;  // >= 0
};

struct VmfFitOptions {
  int lobes = ST_VMF_LOBES;        // lobes the fit uses (1..ST_VMF_LOBES); the rest get weight 0
  int max_iterations = 200;
  double tolerance = 1e-7;         // stop when the mean log-likelihood changes less than this
  double weight_prior = 0.01;      // Dirichlet pseudo-count added to each lobe's weight
  double mean_cosine_prior = 0.0;  // the mean resultant length a lobe is pulled toward (0: uniform)
  double mean_cosine_strength = 0.2;  // pseudo-samples behind that prior
  double kappa_init = 5.0;
  double kappa_max = 3.0e4;        // a sun seen from the ground has kappa ~ 5e4; lobes stay below
  uint64_t seed = 1;               // the initialisation's generator
};

struct VmfFitResult {
  st_vmf_mixture mixture;
  int iterations = 0;
  double log_likelihood = 0;  // weighted mean log-density of the samples under the fit
  double effective_samples = 0;  // Kish: (sum w)^2 / sum w^2
};

// Fits a mixture to the samples. No samples (or zero total weight): the uniform mixture (all
// weights 0).
VmfFitResult fit_vmf_mixture(const std::vector<DirectionalSample>& samples, const VmfFitOptions& options = {});

// kappa with coth kappa - 1/kappa = r (0 <= r < 1), the sphere's mean resultant length inverted.
double vmf_kappa_from_mean_cosine(double r);
// coth kappa - 1/kappa: the mean cosine to the mean direction of a lobe of concentration kappa.
double vmf_mean_cosine(double kappa);

}  // namespace spectrack
