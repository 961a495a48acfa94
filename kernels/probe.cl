/* probe.cl: kernels for tests and benchmarks that call the renderer's own device functions in
 * isolation: density lookups, majorant cells, free-path sampling and transmittance along a
 * given ray. Each item uses its own random stream (pixel = item index, stream = 7). */
#include "types.h"
#include "rng.h"
#include "sampling.h"
#include "spectrum.h"
#include "phase.h"
#include "medium.h"
#include "majorant.h"
#include "tracking.h"
#include "transmittance.h"


/* Density of medium `medium` at world points (xyz) at times w (seconds; a moving medium's). */
__kernel void k_probe_density(__constant const st_scene* scene, __global const uint* grids,
                              __global const float4* points, __global float* out, int medium, uint n) {
  uint i = get_global_id(0);
  if (i >= n) return;
  uint lookups = 0;
  st_rng rng = rng_make(scene->seed, i, 3u, 0u, 7u, 0u); /* stochastic lookups: one draw */
  out[i] = medium_density(scene, &scene->media[medium], grids, points[i].xyz, points[i].w, &lookups, &rng);
}

/* (dmax, dmin) the walk uses at each world point: its fine cell's (one level), or in the
 * hierarchy its group's at its block's level ((-1,-1) outside the majorant box). */
__kernel void k_probe_majorant(__constant const st_scene* scene, __global const float2* maj,
                               __global const float4* points, __global float2* out, int medium, uint n) {
  uint i = get_global_id(0);
  if (i >= n) return;
  __constant const st_medium* m = &scene->media[medium];
  float3 pi = medium_to_index(m, points[i].xyz);
  if (!medium_box_contains(m, pi)) {
    out[i] = (float2)(-1.0f, -1.0f);
    return;
  }
  int3 c = convert_int3_rtn((pi - m->maj_origin.xyz) / m->maj_origin.w);
  c = clamp(c, (int3)(0), (int3)(m->maj_dims[0], m->maj_dims[1], m->maj_dims[2]) - 1);
  out[i] = majorant_bounds_at(m, maj, c);
}

/* The majorant segments of medium `medium`'s DDA along the world ray (o, d) from t = 0: item 0
 * writes (t0, t1, dmax, dmin) of each segment inside the majorant box, in order (zero-length
 * ones at edges and corners included), then (-1, -1, -1, -1) up to n. */
__kernel void k_probe_segments(__constant const st_scene* scene, __global const float2* maj, float4 o, float4 d,
                               int medium, __global float4* out, uint n) {
  if (get_global_id(0) != 0) return;
  __constant const st_medium* m = &scene->media[medium];
  st_dda s;
  dda_init(m, maj, &s, o.xyz, d.xyz, 0.0f);
  float t0 = s.state == ST_DDA_INSIDE ? 0.0f : s.seg_end;
  uint k = 0;
  while (s.state != ST_DDA_DONE && k < n) {
    if (s.state == ST_DDA_INSIDE) {
      out[k++] = (float4)(t0, s.seg_end, s.dmax, s.dmin);
      t0 = s.seg_end;
    }
    dda_advance(m, maj, &s);
  }
  for (; k < n; ++k) out[k] = (float4)(-1.0f);
}

/* Free-path sampling from (o, d) through the scene: out[i] = (t of the first real collision or
 * INFINITY on escape, event, beta of the channel(s) after the event (x), lookups). channel < 0:
 * all channels (mask rgb); else a one-channel path. */
__kernel void k_probe_track(__constant const st_scene* scene, __global const uint* grids, __global const float2* maj,
                            float4 o, float4 d, int channel, __global float4* out, __global float4* beta_out, uint n) {
  uint i = get_global_id(0);
  if (i >= n) return;
  st_rng rng = rng_make(scene->seed, i, 0u, 0u, 7u, 0u);
  float4 mask = channel < 0 ? scene_lanes(scene) : one_hot(channel);
  float4 beta = mask, L = (float4)(0.0f), r_u = mask;
  int hero = draw_hero(scene, &rng);
  st_track_stats st;
  track_stats_clear(&st);
  float t = 0.0f;
  int medium = 0, ev;
  do {
    ev = track_path(scene, grids, maj, o.xyz, normalize(d.xyz), &t, INFINITY, &beta, &r_u, hero, mask, &L, &medium, &rng,
                    scene->iteration_budget, &st);
  } while (ev == ST_EV_BUDGET);
  out[i] = (float4)(ev == ST_EV_ESCAPE ? INFINITY : t, (float)ev, (float)st.lookups, (float)st.dda_steps);
  beta_out[i] = beta;
}

/* Transmittance from (o, d) to the end of every medium, per channel, by the scene's estimator
 * (ratio tracking or ray marching); out_stats[i] = (density lookups, DDA steps, 0, 0). */
__kernel void k_probe_transmittance(__constant const st_scene* scene, __global const uint* grids,
                                    __global const float2* maj, float4 o, float4 d, __global float4* out,
                                    __global float4* out_stats, uint n) {
  uint i = get_global_id(0);
  if (i >= n) return;
  st_rng rng = rng_make(scene->seed, i, 0u, 0u, 7u, 0u);
  float4 mask = scene_lanes(scene);
  st_trans tr;
  transmittance_begin(&tr, mask);
  st_track_stats st;
  track_stats_clear(&st);
  float t = 0.0f;
  while (!transmittance_estimate(scene, grids, maj, o.xyz, normalize(d.xyz), INFINITY, &t, &tr, mask, mask, &rng,
                                 scene->iteration_budget, &st)) {
  }
  out[i] = tr.T;
  out_stats[i] = (float4)((float)st.lookups, (float)st.dda_steps, 0.0f, 0.0f);
}

/* Infinite-medium albedo problem (docs/estimators.md, 'Tests that catch bias'): a walk from o in a random direction,
 * isotropic scattering, until absorption. out_scatter: sum of the path weight after each real
 * scattering event (exact: albedo / (1 - albedo) per channel for a spatially constant albedo);
 * out_absorb: the emission score with Le = 1 (exact: 1); out_absorb.w = 1 if the walk escaped.
 * With absorption=weight the walk ends by the renderer's Russian roulette (scatter.cl). */
__kernel void k_probe_albedo(__constant const st_scene* scene, __global const uint* grids, __global const float2* maj,
                             float4 origin, int channel, __global float4* out_scatter, __global float4* out_absorb,
                             uint n) {
  uint i = get_global_id(0);
  if (i >= n) return;
  st_rng rng = rng_make(scene->seed, i, 1u, 0u, 7u, 0u);
  float4 mask = channel < 0 ? scene_lanes(scene) : one_hot(channel);
  float4 beta = mask, L = (float4)(0.0f), sum = (float4)(0.0f), r_u = mask;
  int hero = draw_hero(scene, &rng);
  st_track_stats st;
  track_stats_clear(&st);
  float3 o = origin.xyz;
  float3 d = sample_uniform_sphere(rng_uniform(&rng), rng_uniform(&rng));
  float t = 0.0f, escaped = 0.0f;
  for (int events = 0; events < 1000000; ++events) {
    int medium = 0;
    int ev = track_path(scene, grids, maj, o, d, &t, INFINITY, &beta, &r_u, hero, mask, &L, &medium, &rng, scene->iteration_budget, &st);
    if (ev == ST_EV_BUDGET) continue;
    if (ev == ST_EV_ESCAPE) { escaped = 1.0f; break; }
    if (ev == ST_EV_ABSORB) break;
    sum += beta * mask;
    if (absorption_as_weight(scene) && events >= 2) { /* scatter.cl's roulette, from depth 3 on */
      float survive = fmin(1.0f, masked_max(fabs(beta), mask));
      if (survive < 1.0f) {
        if (rng_uniform(&rng) >= survive) break;
        beta /= survive;
      }
    }
    o = o + t * d;
    t = 0.0f;
    d = sample_uniform_sphere(rng_uniform(&rng), rng_uniform(&rng));
  }
  out_scatter[i] = (float4)(sum.xyz, st.max_beta);
  out_absorb[i] = (float4)(L.xyz, escaped);
}

/* Phase-function sampling around +z, phase (type, g, b) (phase.h): out[2i] = (cos theta of the
 * sample, its pdf as the sampler reports it, phase value of the direction, |direction| - 1),
 * out[2i + 1] = (the phase value the sampler reports, the uniforms the sample drew, 0, 0). */
__kernel void k_probe_phase(__constant const st_scene* scene, int type, float g, float4 b, __global float4* out, uint n) {
  uint i = get_global_id(0);
  if (i >= n) return;
  st_rng rng = rng_make(scene->seed, i, 2u, 0u, 7u, 0u);
  float pdf, f;
  float3 d = (float3)(0.0f, 0.0f, 1.0f);
  const float u1 = rng_uniform(&rng), u2 = rng_uniform(&rng);
  float3 wi = phase_sample_any(type, g, b, d, u1, u2, &rng, &pdf, &f);
  out[2u * i] = (float4)(wi.z, pdf, phase_eval_any(type, g, b, wi.z), length(wi) - 1.0f);
  out[2u * i + 1u] = (float4)(f, (float)rng_draw_index(&rng), 0.0f, 0.0f);
}

/* The phase function (type, g, b) at given cosines: out[i] = (value, value). */
__kernel void k_probe_phase_eval(__constant const st_scene* scene, int type, float g, float4 b,
                                 __global const float* cos_theta, __global float2* out, uint n) {
  uint i = get_global_id(0);
  if (i >= n) return;
  const float v = phase_eval_any(type, g, b, cos_theta[i]);
  out[i] = (float2)(v, v);
}

/* Raw uniforms of the renderer's generator (kernels/rng.h): item i draws n_draws uniforms from
 * draw first_draw of the stream (pixel, sample, channel, stream) = base, with component `axis`
 * (0 pixel, 1 sample, 2 channel, 3 stream) increased by i, so neighbouring items are neighbouring
 * streams. resume_every > 0 rebuilds the generator from its saved draw index every resume_every
 * draws, as a path re-queued between launches does: the values must not change.
 * out[i * n_draws + k] = draw first_draw + k of item i's stream. */
__kernel void k_probe_uniforms(__constant const st_scene* scene, uint4 base, int axis, uint first_draw, uint n_draws,
                               uint resume_every, __global float* out, uint n) {
  uint i = get_global_id(0);
  if (i >= n) return;
  uint4 c = base;
  if (axis == 0) c.x += i;
  else if (axis == 1) c.y += i;
  else if (axis == 2) c.z += i;
  else c.w += i;
  st_rng rng = rng_make(scene->seed, c.x, c.y, c.z, c.w, first_draw);
  for (uint k = 0; k < n_draws; ++k) {
    if (resume_every > 0u && k > 0u && k % resume_every == 0u)
      rng = rng_make(scene->seed, c.x, c.y, c.z, c.w, rng_draw_index(&rng));
    out[(ulong)i * n_draws + k] = rng_uniform(&rng);
  }
}

/* The bare Philox4x32-10 block function: io[2i] = counter, io[2i+1].xy = key in; io[2i] = output. */
__kernel void k_probe_philox(__global uint4* io, uint n) {
  uint i = get_global_id(0);
  if (i >= n) return;
  io[2 * i] = st_philox4x32_10(io[2 * i], io[2 * i + 1].xy);
}

/* Spectral mode's functions (kernels/spectrum.h): item i takes in[i] = (r, g, b, u) and writes
 * out[4i] = the colour's coefficients (table lookup), out[4i+1] = the four wavelengths of u,
 * out[4i+2] = their pdfs, out[4i+3] = (film rgb of the colour's spectrum as a radiance at them, 0)
 * and spec[i] = the spectrum at them. */
__kernel void k_probe_spectrum(__global const float* table, int res, __global const float4* in, __global float4* out,
                               __global float4* spec, uint n) {
  uint i = get_global_id(0);
  if (i >= n) return;
  float4 coeffs = rgb2spec_lookup(table, res, in[i].xyz);
  float4 lambda = sample_wavelengths(in[i].w, 4);
  float4 pdf = wavelength_pdfs(lambda);
  float4 s = rgb2spec_eval(coeffs, lambda);
  out[4 * i] = coeffs;
  out[4 * i + 1] = lambda;
  out[4 * i + 2] = pdf;
  out[4 * i + 3] = film_rgb(s, lambda, pdf, 4);
  spec[i] = s;
}
