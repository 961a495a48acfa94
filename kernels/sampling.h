/* sampling.h: small geometric and sampling helpers (float3 math, exponential free flights,
 * directions on the sphere and in a cone, orthonormal frames). Precise log/exp only: the
 * native_* functions have implementation-defined accuracy (docs/estimators.md, 'Walking the grid'). */
#ifndef SPECTRACK_SAMPLING_H
#define SPECTRACK_SAMPLING_H

#define ST_PI 3.14159265358979323846f
#define ST_INV_4PI 0.07957747154594767f

/* Free flight with rate mu: -ln(1 - u) / mu (u in [0,1), so the log is finite). */
inline float sample_exponential(float u, float mu) { return -log(1.0f - u) / mu; }

inline float max3(float4 v) { return fmax(v.x, fmax(v.y, v.z)); }
inline float sum3(float4 v) { return v.x + v.y + v.z; }
/* The mask of lane c (0..3: a colour channel, or a wavelength in spectral mode), and component c of v. */
inline float4 one_hot(int c) {
  return (float4)(c == 0 ? 1.0f : 0.0f, c == 1 ? 1.0f : 0.0f, c == 2 ? 1.0f : 0.0f, c == 3 ? 1.0f : 0.0f);
}
inline float channel_of(float4 v, int c) { return c == 0 ? v.x : (c == 1 ? v.y : (c == 2 ? v.z : v.w)); }

/* Reductions over the lanes a path carries (mask entries are 0 or 1). Lane w (spectral mode's
 * fourth wavelength) joins only where the mask has it, after the other three, so that a mask
 * without it gives exactly the three-lane result whatever w holds. */
inline float masked_max(float4 v, float4 mask) {
  float4 m = select((float4)(-INFINITY), v, isnotequal(mask, (float4)(0.0f)));
  return fmax(fmax(m.x, fmax(m.y, m.z)), m.w);
}
inline float masked_avg(float4 v, float4 mask) {
  return mask.w != 0.0f ? (sum3(v * mask) + v.w * mask.w) / (sum3(mask) + mask.w) : sum3(v * mask) / sum3(mask);
}

inline void make_frame(float3 n, float3* t, float3* b) {
  /* Duff et al. 2017, "Building an orthonormal basis, revisited" */
  float s = n.z >= 0.0f ? 1.0f : -1.0f;
  float a = -1.0f / (s + n.z);
  float c = n.x * n.y * a;
  *t = (float3)(1.0f + s * n.x * n.x * a, s * c, -s * n.x);
  *b = (float3)(c, s + n.y * n.y * a, -n.y);
}

inline float3 sample_uniform_sphere(float u1, float u2) {
  float z = 1.0f - 2.0f * u1;
  float r = sqrt(fmax(0.0f, 1.0f - z * z));
  float phi = 2.0f * ST_PI * u2;
  return (float3)(r * cos(phi), r * sin(phi), z);
}

/* A uniform point of the unit disc from two uniforms (Shirley and Chiu's concentric map, as
 * pbrt-v4's SampleUniformDiskConcentric): strata of the square stay compact on the disc. */
inline float2 sample_concentric_disk(float u1, float u2) {
  const float a = 2.0f * u1 - 1.0f, b = 2.0f * u2 - 1.0f;
  if (a == 0.0f && b == 0.0f) return (float2)(0.0f);
  float r, theta;
  if (fabs(a) > fabs(b)) {
    r = a;
    theta = 0.25f * ST_PI * (b / a);
  } else {
    r = b;
    theta = 0.5f * ST_PI - 0.25f * ST_PI * (a / b);
  }
  return r * (float2)(cos(theta), sin(theta));
}

/* The direction at polar angle (cos_theta, sin_theta) and azimuth 2 pi u around a unit axis. */
inline float3 direction_around(float3 axis, float cos_theta, float sin_theta, float u) {
  float s = sin_theta;
  float phi = 2.0f * ST_PI * u;
  float3 t, b;
  make_frame(axis, &t, &b);
  float3 w = s * cos(phi) * t + s * sin(phi) * b + cos_theta * axis;
  /* w is a unit vector to within a few ulp when axis is; renormalising it anyway moved cos theta by
   * ulps where rsqrt is approximate (NVIDIA), and near cos = +-1 a few ulps are the whole lobe of
   * HG at |g| = 0.999 (Sampling.PhaseSamplingFollowsHenyeyGreenstein failed there). Only a length
   * that has drifted measurably is corrected, so drift cannot build up over a long path. */
  float l2 = dot(w, w);
  return fabs(l2 - 1.0f) > 1e-6f ? w * rsqrt(l2) : w;
}

/* Uniform direction in the cone of half-angle acos(cos_max) around axis. */
inline float3 sample_cone(float3 axis, float cos_max, float u1, float u2) {
  float one_minus_cos = u1 * (1.0f - cos_max);
  float c = 1.0f - one_minus_cos;
  return direction_around(axis, c, sqrt(fmax(0.0f, one_minus_cos * (2.0f - one_minus_cos))), u2);
}

#endif
