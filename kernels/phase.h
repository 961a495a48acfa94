/* phase.h: isotropic, Henyey-Greenstein and Draine-blend phase functions.
 * cos_theta is the cosine between the propagation direction before the event and the new
 * direction (g > 0 scatters forward). HG is sampled exactly, so f / pdf = 1.
 * For |g| near 1 the lobe is narrower than float resolution of cos_theta near +-1, so sampling
 * works with 1 - cos and 1 + cos in product forms (no cancellation), the HG denominator is
 * evaluated from (1 -+ g)^2 plus a small term, and the pdf reported for MIS is the phase function
 * of the final direction, computed exactly as next-event estimation computes it.
 *
 * The Draine blend (ST_PHASE_DRAINE_BLEND, types.h) is f = (1 - w) D(g1, a1) + w D(g2, a2) with
 * Draine's phase function D(g, a) = HG(g) (1 + a cos^2) / (1 + a (1 + 2 g^2) / 3). It is sampled
 * exactly, so f / pdf = 1 as for HG: a lobe is chosen with its weight, then rejection sampling
 * draws from the lobe's HG factor (exactly, as above) and accepts cos with probability
 * (1 + a cos^2) / (1 + a), which leaves D(g, a). The expected number of proposals is
 * (1 + a) / (1 + a (1 + 2 g^2) / 3) < 3 (1.8 for the Mie fit's Draine lobes, 1.5 for Rayleigh); the
 * extra uniforms come from the path's own stream (rng), so paths stay keyed by (pixel, sample,
 * channel). After ST_PHASE_MAX_PROPOSALS rejections the last proposal is kept, an event of
 * probability below (2/3)^64 = 5e-12. The closed-form inversion of the Draine CDF is not used: it
 * loses digits as 1 / g^3 in float near g = 0, and a weighted sampler's weights multiply over a
 * dense medium's many bounces. */
#ifndef SPECTRACK_PHASE_H
#define SPECTRACK_PHASE_H

#include "features.h"
#include "rng.h"
#include "sampling.h"

inline float phase_hg(float g, float cos_theta) {
  /* 1 + g^2 - 2 g cos = (1 - g)^2 + 2 g (1 - cos) = (1 + g)^2 - 2 g (1 + cos) */
  float denom = cos_theta >= 0.0f ? (1.0f - g) * (1.0f - g) + 2.0f * g * (1.0f - cos_theta)
                                  : (1.0f + g) * (1.0f + g) - 2.0f * g * (1.0f + cos_theta);
  return ST_INV_4PI * (1.0f - g * g) / (denom * sqrt(fmax(denom, 1e-30f)));
}

/* Draine's phase function: HG(g) times (1 + alpha cos^2), normalised. */
inline float phase_draine(float g, float alpha, float cos_theta) {
  return phase_hg(g, cos_theta) * (1.0f + alpha * cos_theta * cos_theta) /
         (1.0f + alpha * (1.0f + 2.0f * g * g) * (1.0f / 3.0f));
}

/* The Draine blend's value; b = (alpha1, g2, alpha2, w). */
inline float phase_blend_eval(float g1, float4 b, float cos_theta) {
  return (1.0f - b.w) * phase_draine(g1, b.x, cos_theta) + b.w * phase_draine(b.y, b.z, cos_theta);
}
#define ST_PHASE_MAX_PROPOSALS 64

/* The *_any forms serve every phase type (the probes call them); the renderer's forms drop HG and
 * the Draine blend when the scene has none (features.h). */
inline float phase_eval_any(int type, float g, float4 b, float cos_theta) {
  if (type == ST_PHASE_DRAINE_BLEND) return phase_blend_eval(g, b, cos_theta);
  return type == ST_PHASE_HG ? phase_hg(g, cos_theta) : ST_INV_4PI;
}
inline int phase_type_compiled(int type) {
  if (type == ST_PHASE_HG) return ST_HAS_HG ? type : ST_PHASE_ISOTROPIC;
  if (type == ST_PHASE_DRAINE_BLEND) return ST_HAS_PHASE_SET ? type : ST_PHASE_ISOTROPIC;
  return ST_PHASE_ISOTROPIC;
}
inline float phase_eval(int type, float g, float4 b, float cos_theta) {
  return phase_eval_any(phase_type_compiled(type), g, b, cos_theta);
}

/* cos and sin of a Henyey-Greenstein sample for uniform u1 (g != 0):
 * s = (1 - g^2) / (1 - g + 2 g u); cos = (1 + g^2 - s^2) / (2 g), written as
 * 1 - cos = (1 - g)(1 - u)(s + 1 - g) / (1 - g + 2 g u) and
 * 1 + cos = (1 + g) u (s + 1 + g) / (1 - g + 2 g u) */
inline float hg_sample_cos(float g, float u1, float* sin_theta) {
  float den = fma(2.0f * g, u1, 1.0f - g);
  float s = (1.0f - g) * (1.0f + g) / den;
  float one_minus = (1.0f - g) * (1.0f - u1) * (s + 1.0f - g) / den;
  float one_plus = (1.0f + g) * u1 * (s + 1.0f + g) / den;
  one_minus = clamp(one_minus, 0.0f, 2.0f);
  one_plus = clamp(one_plus, 0.0f, 2.0f);
  *sin_theta = sqrt(one_minus * one_plus);
  return one_minus < one_plus ? 1.0f - one_minus : one_plus - 1.0f;
}

/* The Draine blend's direction: lobe 2 with probability w (u1 rescaled within the choice), then
 * rejection sampling of the lobe from its HG factor (further uniforms from rng); writes the
 * phase value of the final direction as both *pdf and *f. */
inline float3 phase_blend_sample(float g1, float4 b, float3 d, float u1, float u2, st_rng* rng, float* pdf, float* f) {
  int second = u1 < b.w;
  float u = second ? u1 / b.w : (u1 - b.w) / (1.0f - b.w);
  u = clamp(u, 0.0f, 0x1.fffffep-1f);
  const float g = second ? b.y : g1, alpha = second ? b.z : b.x;
  float cos_theta = 0.0f, sin_theta = 0.0f;
  for (int k = 0; k < ST_PHASE_MAX_PROPOSALS; ++k) {
    if (k > 0) u = rng_uniform(rng);
    if (g == 0.0f) {
      cos_theta = 1.0f - 2.0f * u;
      sin_theta = sqrt(fmax(0.0f, 4.0f * u * (1.0f - u)));
    } else {
      cos_theta = hg_sample_cos(g, u, &sin_theta);
    }
    if (alpha == 0.0f || rng_uniform(rng) * (1.0f + alpha) < 1.0f + alpha * cos_theta * cos_theta) break;
  }
  float3 wi = direction_around(d, cos_theta, sin_theta, u2);
  *pdf = phase_blend_eval(g1, b, dot(d, wi));
  *f = *pdf;
  return wi;
}

/* Samples a new direction around d from uniforms u1, u2 (the Draine blend draws more from rng);
 * returns it and writes its pdf and the phase value *f, equal (exact sampling). */
inline float3 phase_sample_any(int type, float g, float4 b, float3 d, float u1, float u2, st_rng* rng, float* pdf,
                               float* f) {
  if (type == ST_PHASE_DRAINE_BLEND) return phase_blend_sample(g, b, d, u1, u2, rng, pdf, f);
  float cos_theta, sin_theta;
  if (type != ST_PHASE_HG || fabs(g) < 1e-3f) {
    cos_theta = 1.0f - 2.0f * u1;
    sin_theta = sqrt(fmax(0.0f, 4.0f * u1 * (1.0f - u1)));
  } else {
    cos_theta = hg_sample_cos(g, u1, &sin_theta);
  }
  float3 wi = direction_around(d, cos_theta, sin_theta, u2);
  *pdf = phase_eval_any(type, g, b, dot(d, wi));
  *f = *pdf;
  return wi;
}
inline float3 phase_sample(int type, float g, float4 b, float3 d, float u1, float u2, st_rng* rng, float* pdf,
                           float* f) {
  return phase_sample_any(phase_type_compiled(type), g, b, d, u1, u2, rng, pdf, f);
}

#endif
