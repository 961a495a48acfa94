/* phase.h: isotropic and Henyey-Greenstein phase functions.
 * cos_theta is the cosine between the propagation direction before the event and the new
 * direction (g > 0 scatters forward). HG is sampled exactly, so f / pdf = 1. */
#ifndef SPECTRACK_PHASE_H
#define SPECTRACK_PHASE_H

inline float phase_hg(float g, float cos_theta) {
  float denom = 1.0f + g * g - 2.0f * g * cos_theta;
  return ST_INV_4PI * (1.0f - g * g) / (denom * sqrt(fmax(denom, 1e-30f)));
}

inline float phase_eval(int type, float g, float cos_theta) {
  return type == ST_PHASE_HG ? phase_hg(g, cos_theta) : ST_INV_4PI;
}

/* Samples a new direction around d; returns it and writes its pdf (= the phase value). */
inline float3 phase_sample(int type, float g, float3 d, float u1, float u2, float* pdf) {
  float cos_theta;
  if (type != ST_PHASE_HG || fabs(g) < 1e-3f) {
    cos_theta = 1.0f - 2.0f * u1;
  } else {
    float sq = (1.0f - g * g) / (1.0f - g + 2.0f * g * u1);
    cos_theta = clamp((1.0f + g * g - sq * sq) / (2.0f * g), -1.0f, 1.0f);
  }
  *pdf = phase_eval(type, g, cos_theta);
  return direction_around(d, cos_theta, u2);
}

#endif
