/* light.h: environment (uniform or lat-long map), directional (delta or disc), point and spot
 * lights: radiance seen along a direction, direction sampling for next-event estimation, and the pdf
 * of that sampling for MIS against phase sampling (power heuristic, directions only:
 * docs/estimators.md, 'Spectral MIS'). Point and spot lights (features.h ST_HAS_LOCAL_LIGHT) are
 * delta in direction: a shadow ray of length r towards the position, radiant intensity I / r^2, no
 * MIS (phase sampling never hits them); a spot's I falls from full inside cone_angle - cone_delta
 * to 0 at cone_angle by a smoothstep in cos theta (pbrt-v4's SpotLight). A sphere light
 * (features.h ST_HAS_SPHERE_LIGHT) has an area: its surface's radiance, seen by rays that reach it
 * (track.cl ends them there, ground.h surface_distance) and sampled uniformly in the cone it subtends
 * (pbrt-v4's sphere sampling outside the sphere), so MIS with phase sampling applies; its shadow
 * rays end at its surface.
 * Lat-long convention: v = acos(d.y) / pi (row 0 looks up, +y), u = 0.5 + atan2(d.x, -d.z) / (2 pi)
 * + map_turn (the image centre looks along -z, the map then turned right-handedly about +y by
 * rotate_deg = 360 map_turn, as a medium's transform turns: 90 takes the centre to -x). The map is
 * sampled in proportion to max(rgb) * sin(theta). */
#ifndef SPECTRACK_LIGHT_H
#define SPECTRACK_LIGHT_H

#include "types.h"
#include "features.h"
#include "sampling.h"
#include "spectrum.h"
#include "phase.h"

inline float2 env_dir_to_uv(__constant const st_light* l, float3 d) {
  float v = acos(clamp(d.y, -1.0f, 1.0f)) / ST_PI;
  float u = 0.5f + atan2(d.x, -d.z) / (2.0f * ST_PI);
  if (l->map_turn != 0.0f) u += l->map_turn;  /* a turn by rotate_deg lowers atan2(x, -z) by as much */
  return (float2)(u - floor(u), v);
}
inline float3 env_uv_to_dir(__constant const st_light* l, float2 uv) {
  float u = uv.x;
  if (l->map_turn != 0.0f) u -= l->map_turn;
  float theta = uv.y * ST_PI, phi = (u - 0.5f) * 2.0f * ST_PI;
  float s = sin(theta);
  return (float3)(s * sin(phi), cos(theta), -s * cos(phi));
}

inline __global const float* env_texel_at(__constant const st_light* l, __global const float* env, float2 uv) {
  int x = min((int)(uv.x * l->map_width), l->map_width - 1);
  int y = min((int)(uv.y * l->map_height), l->map_height - 1);
  return env + l->map_offset + 4u * (uint)(y * l->map_width + x);
}

/* The texel's rgb (w = 0); in spectral mode (l->spectral) texels hold the sigmoid coefficients of
 * their colour instead (src/scene/spectral_pack.cpp: rgb2spec_unbounded_lookup, whose scale, lane
 * w, is exactly twice the colour's largest component). */
inline float4 env_texel(__constant const st_light* l, __global const float* env, float2 uv) {
  __global const float* px = env_texel_at(l, env, uv);
  return (float4)(px[0], px[1], px[2], 0.0f);
}

/* The texel's largest rgb component: what the sampling distribution is built on, in both modes. */
inline float env_texel_max(__constant const st_light* l, __global const float* env, float2 uv) {
  if (ST_HAS_SPECTRAL && l->spectral) return 0.5f * env_texel_at(l, env, uv)[3];
  return max3(env_texel(l, env, uv));
}

/* Index i with cdf[i] <= u < cdf[i+1] in a cdf of n+1 entries (cdf[0] = 0, cdf[n] = 1). */
inline int cdf_find(__global const float* cdf, int n, float u) {
  int lo = 0, hi = n;
  while (hi - lo > 1) {
    int mid = (lo + hi) / 2;
    if (cdf[mid] <= u) lo = mid; else hi = mid;
  }
  return lo;
}

/* The solid-angle pdf of light_sample's direction d. The CDFs draw a texel by f = max(rgb) x
 * sin(theta_c), theta_c its row's centre (src/scene/pack_lights.cpp add_env_cdf), then (u, v)
 * uniformly in it: the density in (u, v) is f / map_integral, constant over the texel, and a
 * direction's solid angle is 2 pi^2 sin(theta) du dv at its own theta. */
inline float env_map_pdf(__constant const st_light* l, __global const float* env, float3 d) {
  float2 uv = env_dir_to_uv(l, d);
  float s = sqrt(fmax(0.0f, 1.0f - d.y * d.y));
  if (s <= 0.0f || l->map_integral <= 0.0f) return 0.0f;
  int row = min((int)(uv.y * l->map_height), l->map_height - 1);
  float f = env_texel_max(l, env, uv) * sin(ST_PI * ((float)row + 0.5f) / (float)l->map_height);
  return f / l->map_integral / (2.0f * ST_PI * ST_PI * s);
}

/* The light's radiance (uniform environment, disc) or scale (map): rgb, or in spectral mode its
 * spectrum at the path's wavelengths (st_light.spectral: an upsampled colour times D65). */
inline float4 light_radiance(__constant const st_light* l, float4 lambda) {
  return ST_HAS_SPECTRAL && l->spectral ? illuminant_at(l->radiance, lambda) : l->radiance;
}

/* An environment map's radiance along d: scale * the texel's rgb, or in spectral mode scale * the
 * texel's spectrum times D65 at the path's wavelengths (the map's scale stays a number). */
inline float4 env_map_Le(__constant const st_light* l, __global const float* env, float3 d, float4 lambda) {
  if (ST_HAS_SPECTRAL && l->spectral) {
    __global const float* px = env_texel_at(l, env, env_dir_to_uv(l, d));
    return l->radiance.x * illuminant_at((float4)(px[0], px[1], px[2], px[3]), lambda);
  }
  return l->radiance * env_texel(l, env, env_dir_to_uv(l, d));
}

/* Radiance arriving along direction d (pointing away from the scene) from light l at infinity (0 for
 * local lights). */
inline float4 light_Le(__constant const st_light* l, __global const float* env, float3 d, float4 lambda) {
  if (l->type == ST_LIGHT_ENV_UNIFORM) return light_radiance(l, lambda);
  if (ST_HAS_ENV_MAP && l->type == ST_LIGHT_ENV_MAP) return env_map_Le(l, env, d, lambda);
  if (l->is_delta) return (float4)(0.0f);
  if (ST_HAS_SPHERE_LIGHT && l->type == ST_LIGHT_SPHERE) return (float4)(0.0f);
  return dot(d, l->direction.xyz) >= l->cos_max ? light_radiance(l, lambda) : (float4)(0.0f);
}

/* pdf (solid angle) with which light_sample picks d, for lights at infinity; 0 for delta lights (a
 * sphere's: sphere_light_pdf). */
inline float light_pdf(__constant const st_light* l, __global const float* env, float3 d) {
  if (l->type == ST_LIGHT_ENV_UNIFORM) return ST_INV_4PI;
  if (ST_HAS_ENV_MAP && l->type == ST_LIGHT_ENV_MAP) return env_map_pdf(l, env, d);
  if (l->is_delta) return 0.0f;
  if (ST_HAS_SPHERE_LIGHT && l->type == ST_LIGHT_SPHERE) return 0.0f;
  return dot(d, l->direction.xyz) >= l->cos_max ? l->pdf_cone : 0.0f;
}

/* Hermite smoothstep of x from a (0) to b (1); a step at a when a == b (pbrt-v4's SmoothStep). */
inline float smooth_step(float a, float b, float x) {
  if (a == b) return x < a ? 0.0f : 1.0f;
  float t = clamp((x - a) / (b - a), 0.0f, 1.0f);
  return t * t * (3.0f - 2.0f * t);
}

/* A local light's intensity factor towards unit direction w_out (from the light): 1 for a point
 * light, a spot's falloff in cos theta from its axis. */
inline float local_light_falloff(__constant const st_light* l, float3 w_out) {
  if (l->type != ST_LIGHT_SPOT) return 1.0f;
  return smooth_step(l->cos_max, l->position.w, dot(l->direction.xyz, w_out));
}

/* A point or spot light seen from x: writes the unit direction to it and its distance; returns
 * the irradiance I falloff / r^2 (0 at the light's own position). */
inline float4 local_light_sample(__constant const st_light* l, float3 x, float3* wi, float* dist, float4 lambda) {
  float3 v = l->position.xyz - x;
  float r2 = dot(v, v);
  if (!(r2 > 0.0f)) {
    *wi = (float3)(0.0f, 1.0f, 0.0f);
    *dist = 0.0f;
    return (float4)(0.0f);
  }
  float r = sqrt(r2);
  *wi = v / r;
  *dist = r;
  return light_radiance(l, lambda) * (local_light_falloff(l, -*wi) / r2);
}

/* Distance along the ray (o, d) (d unit) to sphere light l's surface: INFINITY when it misses, 0
 * when o is inside the sphere (the ray ends there, dark). */
inline float sphere_distance(__constant const st_light* l, float3 o, float3 d) {
  const float3 v = l->position.xyz - o;
  const float r2 = l->position.w * l->position.w, b = dot(v, d);
  if (dot(v, v) < r2) return 0.0f;
  const float3 perp = v - b * d; /* the ray's closest approach to the centre */
  const float disc = r2 - dot(perp, perp);
  return b > 0.0f && disc >= 0.0f ? b - sqrt(disc) : INFINITY;
}

/* 1 - cos of the half angle of the cone sphere light l subtends at x (the cone's solid angle over
 * 2 pi; without cancellation for small spheres), 0 from inside it. */
inline float sphere_cone_omc(__constant const st_light* l, float3 x) {
  const float3 v = l->position.xyz - x;
  const float D2 = dot(v, v), r2 = l->position.w * l->position.w;
  if (!(D2 > r2)) return 0.0f;
  const float s2 = r2 / D2;
  return s2 / (1.0f + sqrt(1.0f - s2));
}

/* The solid-angle pdf of sphere_light_sample at x (every direction of the cone alike). */
inline float sphere_light_pdf(__constant const st_light* l, float3 x) {
  const float omc = sphere_cone_omc(l, x);
  return omc > 0.0f ? 1.0f / (2.0f * ST_PI * omc) : 0.0f;
}

/* A direction uniform in the cone sphere light l subtends at x: Le / pdf, the pdf, and where the
 * shadow ray meets the surface (a direction that rounding lets graze past it: its closest approach). */
inline float4 sphere_light_sample(__constant const st_light* l, float3 x, float u1, float u2, float3* wi, float* pdf,
                                  float* t_max, float4 lambda) {
  const float omc = sphere_cone_omc(l, x);
  *wi = (float3)(0.0f, 1.0f, 0.0f);
  *pdf = 0.0f;
  *t_max = 0.0f;
  if (!(omc > 0.0f)) return (float4)(0.0f);
  const float3 v = l->position.xyz - x;
  const float one_minus_cos = u1 * omc;
  *wi = direction_around(normalize(v), 1.0f - one_minus_cos, sqrt(fmax(0.0f, one_minus_cos * (2.0f - one_minus_cos))), u2);
  *pdf = 1.0f / (2.0f * ST_PI * omc);
  const float t = sphere_distance(l, x, *wi);
  *t_max = isinf(t) ? dot(v, *wi) : t;
  return light_radiance(l, lambda) / *pdf;
}

/* Samples a direction towards light l from the scatter position x. Returns Le / pdf (or the
 * irradiance for a delta light) and writes the direction, its pdf (0 for delta) and where the
 * shadow ray ends (*t_max: a local light's distance, INFINITY for lights at infinity). */
inline float4 light_sample(__constant const st_light* l, __global const float* env, float3 x, float u1, float u2,
                           float3* wi, float* pdf, float* t_max, float4 lambda) {
  *t_max = INFINITY;
  if (ST_HAS_SPHERE_LIGHT && l->type == ST_LIGHT_SPHERE) return sphere_light_sample(l, x, u1, u2, wi, pdf, t_max, lambda);
  if (ST_HAS_LOCAL_LIGHT && l->type >= ST_LIGHT_POINT) {
    *pdf = 0.0f;
    return local_light_sample(l, x, wi, t_max, lambda);
  }
  if (l->type == ST_LIGHT_ENV_UNIFORM) {
    *wi = sample_uniform_sphere(u1, u2);
    *pdf = ST_INV_4PI;
    return light_radiance(l, lambda) / ST_INV_4PI;
  }
  if (ST_HAS_ENV_MAP && l->type == ST_LIGHT_ENV_MAP) {
    __global const float* marg = env + l->cdf_offset;
    int H = l->map_height, W = l->map_width;
    int row = cdf_find(marg, H, u1);
    float dv = (u1 - marg[row]) / fmax(marg[row + 1] - marg[row], 1e-30f);
    __global const float* cond = marg + (H + 1) + row * (W + 1);
    int col = cdf_find(cond, W, u2);
    float du = (u2 - cond[col]) / fmax(cond[col + 1] - cond[col], 1e-30f);
    float2 uv = (float2)((col + clamp(du, 0.0f, 1.0f)) / W, (row + clamp(dv, 0.0f, 1.0f)) / H);
    *wi = env_uv_to_dir(l, uv);
    *pdf = env_map_pdf(l, env, *wi);
    return *pdf > 0.0f ? light_Le(l, env, *wi, lambda) / *pdf : (float4)(0.0f);
  }
  if (l->is_delta) {
    *wi = l->direction.xyz;
    *pdf = 0.0f;
    return light_radiance(l, lambda);
  }
  *wi = sample_cone(l->direction.xyz, l->cos_max, u1, u2);
  *pdf = l->pdf_cone;
  return light_radiance(l, lambda) / l->pdf_cone;
}

/* One-light sampling (uniform, power): the light l with select_cdf[l-1] <= u < select_cdf[l] (scene_pack.cpp:
 * lights without power have select_pmf 0 and are never returned). */
inline int light_select(__constant const st_scene* scene, float u) {
  for (int l = 0; l < scene->n_lights - 1; ++l)
    if (u < scene->lights[l].select_cdf && scene->lights[l].select_pmf > 0.0f) return l;
  int last = scene->n_lights - 1;
  while (last > 0 && !(scene->lights[last].select_pmf > 0.0f)) --last;
  return last;
}

/* Light sampling "contribution" (types.h): the unoccluded contribution of light l at a scatter
 * event at x of a medium with phase (phase_type, g, phase), the path travelling along wo, up to
 * the factor beta common to every light: nee_strength times the phase function towards a
 * directional light (its disc's centre), nee_strength alone for an environment (the phase function
 * integrates to 1: exact for a uniform one), and for a local light nee_strength (its mean
 * intensity) times its falloff / r^2 times the phase function towards it. Every phase function is
 * > 0 everywhere, so every light with strength gets a chance (a spot's only where its cone reaches). */
inline float light_contribution(__constant const st_light* l, int phase_type, float g, float4 phase, float3 wo,
                                float3 x) {
  if (ST_HAS_LOCAL_LIGHT && l->type >= ST_LIGHT_POINT) {
    float3 v = l->position.xyz - x;
    float r2 = dot(v, v);
    if (!(r2 > 0.0f)) return 0.0f;
    float3 wi = v / sqrt(r2);
    return l->nee_strength * local_light_falloff(l, -wi) / r2 * phase_eval(phase_type, g, phase, dot(wo, wi));
  }
  if (l->type != ST_LIGHT_DIRECTIONAL) return l->nee_strength;
  return l->nee_strength * phase_eval(phase_type, g, phase, dot(wo, l->direction.xyz));
}

/* The light of contribution sampling for uniform u: l with probability c_l / sum c (c:
 * light_contribution), written to *pmf; -1 when no light has any strength (no shadow ray). */
inline int light_select_contribution(__constant const st_scene* scene, int phase_type, float g, float4 phase, float3 wo,
                                     float3 x, float u, float* pmf) {
  float contrib[ST_MAX_LIGHTS]; /* each light's, evaluated once (a phase function each) */
  float total = 0.0f;
  for (int l = 0; l < ST_MAX_LIGHTS; ++l) {
    if (l >= scene->n_lights) break;
    contrib[l] = light_contribution(&scene->lights[l], phase_type, g, phase, wo, x);
    total += contrib[l];
  }
  if (!(total > 0.0f)) return -1;
  const float target = u * total;
  float acc = 0.0f, c = 0.0f;
  int chosen = -1;
  for (int l = 0; l < ST_MAX_LIGHTS; ++l) {
    if (l >= scene->n_lights) break;
    const float cl = contrib[l];
    if (!(cl > 0.0f)) continue;
    chosen = l; /* the last light with a contribution, should rounding leave target past the sum */
    c = cl;
    acc += cl;
    if (target < acc) break;
  }
  *pmf = c / total;
  return chosen;
}

inline float power_heuristic(float a, float b) {
  float a2 = a * a, b2 = b * b;
  return a2 + b2 > 0.0f ? a2 / (a2 + b2) : 0.0f;
}

#endif
