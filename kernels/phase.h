/* phase.h: isotropic and Henyey-Greenstein phase functions.
 * cos_theta is the cosine between the propagation direction before the event and the new
 * direction (g > 0 scatters forward). HG is sampled exactly, so f / pdf = 1.
 * For |g| near 1 the lobe is narrower than float resolution of cos_theta near +-1, so sampling
 * works with 1 - cos and 1 + cos in product forms (no cancellation), the HG denominator is
 * evaluated from (1 -+ g)^2 plus a small term, and the pdf reported for MIS is the phase function
 * of the final direction, computed exactly as next-event estimation computes it. */
#ifndef SPECTRACK_PHASE_H
#define SPECTRACK_PHASE_H

#include "features.h"
#include "sampling.h"

inline float phase_hg(float g, float cos_theta) {
  /* 1 + g^2 - 2 g cos = (1 - g)^2 + 2 g (1 - cos) = (1 + g)^2 - 2 g (1 + cos) */
  float denom = cos_theta >= 0.0f ? (1.0f - g) * (1.0f - g) + 2.0f * g * (1.0f - cos_theta)
                                  : (1.0f + g) * (1.0f + g) - 2.0f * g * (1.0f + cos_theta);
  return ST_INV_4PI * (1.0f - g * g) / (denom * sqrt(fmax(denom, 1e-30f)));
}

/* The *_any forms serve every phase type (the probes call them); the renderer's forms drop HG
 * when the scene has none (features.h). */
inline float phase_eval_any(int type, float g, float cos_theta) {
  return type == ST_PHASE_HG ? phase_hg(g, cos_theta) : ST_INV_4PI;
}
inline float phase_eval(int type, float g, float cos_theta) {
  return phase_eval_any(ST_HAS_HG ? type : ST_PHASE_ISOTROPIC, g, cos_theta);
}

/* Samples a new direction around d; returns it and writes its pdf (= the phase value). */
inline float3 phase_sample_any(int type, float g, float3 d, float u1, float u2, float* pdf) {
  float cos_theta, sin_theta;
  if (type != ST_PHASE_HG || fabs(g) < 1e-3f) {
    cos_theta = 1.0f - 2.0f * u1;
    sin_theta = sqrt(fmax(0.0f, 4.0f * u1 * (1.0f - u1)));
  } else {
    /* s = (1 - g^2) / (1 - g + 2 g u); cos = (1 + g^2 - s^2) / (2 g), written as
     * 1 - cos = (1 - g)(1 - u)(s + 1 - g) / (1 - g + 2 g u) and
     * 1 + cos = (1 + g) u (s + 1 + g) / (1 - g + 2 g u) */
    float den = fma(2.0f * g, u1, 1.0f - g);
    float s = (1.0f - g) * (1.0f + g) / den;
    float one_minus = (1.0f - g) * (1.0f - u1) * (s + 1.0f - g) / den;
    float one_plus = (1.0f + g) * u1 * (s + 1.0f + g) / den;
    one_minus = clamp(one_minus, 0.0f, 2.0f);
    one_plus = clamp(one_plus, 0.0f, 2.0f);
    cos_theta = one_minus < one_plus ? 1.0f - one_minus : one_plus - 1.0f;
    sin_theta = sqrt(one_minus * one_plus);
  }
  float3 wi = direction_around(d, cos_theta, sin_theta, u2);
  *pdf = phase_eval_any(type, g, dot(d, wi));
  return wi;
}
inline float3 phase_sample(int type, float g, float3 d, float u1, float u2, float* pdf) {
  return phase_sample_any(ST_HAS_HG ? type : ST_PHASE_ISOTROPIC, g, d, u1, u2, pdf);
}

#endif
