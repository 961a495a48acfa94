/* equiangular.h: equi-angular sampling of single scattering towards local lights (Kulla and
 * Fajardo 2012), combined with the tracker's free-flight collisions by multiple importance
 * sampling (docs/equiangular.md).
 *
 * Design. Every path segment (the camera ray, each scattered ray) gets one equi-angular entry, a
 * shadow-ray entry after the lights' (queues.h shadow_lights), made where the segment starts
 * (raygen.cl, scatter.cl: ea_begin): a local light l chosen uniformly (q = 1 / n_local), a
 * distance t in [t0, t1] (the segment inside the hull of the media's boxes, up to the nearest
 * surface) with the equi-angular density p_ea(t) towards the light's position, and the weight
 * beta / (q p_ea(t) + p_ff(t)). k_shadow estimates the transmittance along the segment to
 * x = o + t d (leg 1), samples light l at x as a scatter event would (ea_second_leg: Le / pdf
 * times the sum over media of sigma_s f_phase, with the phase-sampling MIS weight of sphere
 * lights) and estimates the transmittance from x to the light (leg 2). The tracker estimates the
 * same integral by next-event estimation at its real scattering events; k_scatter multiplies its
 * light-l term by p_ff(t) / (q p_ea(t) + p_ff(t)) (ea_flight_weight). The two weights sum to 1 at
 * every t, so the sum is unbiased whatever p_ff is; here p_ff(t) = sigma exp(-sigma (t - t0)),
 * sigma the scene's mean gray majorant extinction (st_scene.equiangular.sigma_t): the tracker's
 * collision density in a homogeneous medium and a stand-in elsewhere (the true one, sigma_s(t)
 * T(t), is known to neither technique). Only the stored segment and the light's position enter
 * the weights, so both techniques compute them alike. */
#ifndef SPECTRACK_EQUIANGULAR_H
#define SPECTRACK_EQUIANGULAR_H

#include "types.h"
#include "features.h"
#include "rng.h"
#include "sampling.h"
#include "medium.h"
#include "phase.h"
#include "light.h"
#include "ground.h"
#include "queues.h"

inline int ea_on(__constant const st_scene* scene) { return ST_HAS_EQUIANGULAR && scene->equiangular.n_local > 0; }
/* The equi-angular entry of segment s of the path in slot `slot` (its place in the shadow ring). */
inline uint ea_entry(__constant const st_scene* scene, uint NL, uint slot, int s) {
  return shadow_entry(slot, NL, shadow_lights(scene), s, scene->n_lights);
}
inline int ea_light_is_target(__constant const st_light* l) { return l->type >= ST_LIGHT_POINT; }

/* The target light of rank floor(u n_local) (-1: none). */
inline int ea_pick(__constant const st_scene* scene, float u) {
  int k = min((int)(u * (float)scene->equiangular.n_local), scene->equiangular.n_local - 1);
  for (int l = 0; l < ST_MAX_LIGHTS; ++l) {
    if (l >= scene->n_lights || !ea_light_is_target(&scene->lights[l])) continue;
    if (k-- == 0) return l;
  }
  return -1;
}

/* The part [*t0, *t1] of the ray (o, d), t >= 0, inside the hull of the media's boxes, up to the
 * nearest surface (empty: *t1 <= *t0). */
inline void ea_interval(__constant const st_scene* scene, float3 o, float3 d, float* t0, float* t1) {
  float lo = INFINITY, hi = 0.0f;
  for (int i = 0; i < ST_KERNEL_MAX_MEDIA; ++i) {
    if (i >= scene->n_media) continue;
    __constant const st_medium* m = &scene->media[i];
    float3 di = medium_dir_to_index(m, d);
    di = select(di, (float3)(0.0f), di == 0.0f); /* -0.0 -> +0.0 */
    float a, b;
    medium_box_interval(m, medium_to_index(m, o), di, &a, &b);
    a = fmax(a, 0.0f);
    if (b > a) {
      lo = fmin(lo, a);
      hi = fmax(hi, b);
    }
  }
  int sphere;
  *t0 = lo;
  *t1 = fmin(hi, surface_distance(scene, o, d, &sphere));
}

/* The equi-angular geometry of a segment (origin, t0 in w; direction, t1 in w) and a point c:
 * delta, the foot of c's perpendicular on the ray, D its length, and the angles of the segment's
 * ends seen from c. 0 where it is degenerate (an empty segment, c on the ray's line): there the
 * technique has density 0 and draws nothing. */
typedef struct {
  float delta, D, theta_a, theta_b;
} st_ea_geom;

inline int ea_geometry(float3 c, float4 seg_o, float4 seg_d, st_ea_geom* g) {
  const float3 v = c - seg_o.xyz;
  g->delta = dot(v, seg_d.xyz);
  g->D = length(v - g->delta * seg_d.xyz);
  const float t0 = seg_o.w, t1 = seg_d.w;
  if (!(t1 > t0) || !isfinite(t1) || !(g->D > 1e-6f * (t1 - t0))) return 0;
  g->theta_a = atan2(t0 - g->delta, g->D);
  g->theta_b = atan2(t1 - g->delta, g->D);
  return g->theta_b > g->theta_a;
}

/* q p_ea(t): the density of the technique's sample at t for light l (0 outside [t0, t1]). */
inline float ea_density(__constant const st_scene* scene, int l, float4 seg_o, float4 seg_d, float t) {
  st_ea_geom g;
  if (!(t >= seg_o.w && t <= seg_d.w) || !ea_geometry(scene->lights[l].position.xyz, seg_o, seg_d, &g)) return 0.0f;
  const float x = t - g.delta;
  return g.D / ((g.theta_b - g.theta_a) * (g.D * g.D + x * x)) / (float)scene->equiangular.n_local;
}

/* p_ff(t): the free-flight density the MIS weights assume (above). */
inline float ea_flight_density(__constant const st_scene* scene, float t0, float t) {
  const float sigma = scene->equiangular.sigma_t;
  return sigma * exp(-sigma * fmax(t - t0, 0.0f));
}

/* The tracker's MIS weight for its light-l sample at a real scattering event at x on the segment
 * of equi-angular entry e (of the n shadow entries): p_ff / (p_ff + q p_ea) (1 for lights the
 * technique never samples). */
inline float ea_flight_weight(__constant const st_scene* scene, ST_SHADOW_STATE shadows, uint n, uint e, int l,
                              float3 x) {
  if (!ea_light_is_target(&scene->lights[l])) return 1.0f;
  st_shadow s;
  shadow_load(shadows, n, e, ST_SHADOW_SEGMENT, &s);
  const float t = dot(x - s.seg_o.xyz, s.seg_d.xyz);
  const float q_pea = ea_density(scene, l, s.seg_o, s.seg_d, t);
  const float p_ff = ea_flight_density(scene, s.seg_o.w, t);
  return q_pea > 0.0f ? p_ff / (p_ff + q_pea) : 1.0f;
}

/* The light sample at the equi-angular point x of an entry's stream (draws 2 and 3, so leg 2
 * finds the same direction again): Le / pdf, the direction, its pdf and the shadow ray's end. */
inline float4 ea_light_sample(__constant const st_scene* scene, __global const float* env, const st_path* p,
                              uint stream, int l, float3 x, float3* wi, float* pdf_l, float* t_max) {
  st_rng rng = path_rng(scene, p, stream, 2u);
  const float u1 = rng_uniform(&rng), u2 = rng_uniform(&rng);
  return light_sample(&scene->lights[l], env, x, u1, u2, wi, pdf_l, t_max, rng.lambda);
}

/* The sum over the media at x of sigma_s f_phase(wo . wi), each medium's term times its MIS weight
 * against phase sampling (light_pdf: the light's pdf times its select_pmf; 0 for a delta light,
 * weight 1), as k_scatter weighs a light sample at a scattering event in that medium. */
inline float4 ea_scattering(__constant const st_scene* scene, __global const uint* grids, float3 x, float3 wo,
                            float3 wi, float light_pdf, st_rng* rng, uint* lookups) {
  float4 sum = (float4)(0.0f);
  for (int i = 0; i < ST_KERNEL_MAX_MEDIA; ++i) {
    if (i >= scene->n_media) continue;
    __constant const st_medium* m = &scene->media[i];
    const float d = medium_density(scene, m, grids, x, rng->time, lookups, rng);
    if (d == 0.0f) continue;
    const float4 tint = medium_has_color(m) ? medium_color(m, grids, x, rng->time, lookups) : (float4)(1.0f);
    float4 sigma_a, sigma_s;
    medium_unit_coeffs(m, grids, tint, rng->lambda, &sigma_a, &sigma_s);
    const float f = phase_eval(m->phase_type, m->g, m->phase, dot(wo, wi));
    const float w = light_pdf > 0.0f ? power_heuristic(light_pdf, f) : 1.0f;
    sum += d * sigma_s * (f * w);
  }
  return sum;
}

/* The equi-angular sample of segment p->depth towards light l at t: its contribution if both
 * transmittances were 1, beta / (q p_ea + p_ff) Le / pdf sum(sigma_s f w) (0: nothing to trace). */
inline float4 ea_unoccluded(__constant const st_scene* scene, __global const uint* grids, __global const float* env,
                            const st_path* p, uint stream, int l, float t, float q_pea, float t0, st_rng* rng,
                            uint* lookups) {
  const float3 x = p->o.xyz + t * p->d.xyz;
  float3 wi;
  float pdf_l, t_max;
  const float4 Le_over_pdf = ea_light_sample(scene, env, p, stream, l, x, &wi, &pdf_l, &t_max);
  const float4 mask = path_mask(scene, p);
  if (!(masked_max(fabs(Le_over_pdf), mask) > 0.0f) || surface_blocks(scene, x, wi, t_max, 0, l)) return (float4)(0.0f);
  const float4 f = ea_scattering(scene, grids, x, p->d.xyz, wi, scene->lights[l].select_pmf * pdf_l, rng, lookups);
  return p->beta * mask * Le_over_pdf * f / (q_pea + ea_flight_density(scene, t0, t));
}

/* Starts the equi-angular entry of the path's segment p->depth (its ray p->o, p->d): stores the
 * segment (always: the tracker's weights read it) and, where the segment crosses a medium and may
 * still scatter (max_depth), draws the light and t from the entry's own stream, evaluates the
 * sample's unoccluded contribution (one density lookup per medium at x) and queues leg 1 unless it
 * is 0 (outside a spot's cone, nothing scattering at x, a surface in the way). */
inline void ea_begin(__constant const st_scene* scene, __global const uint* grids, __global const float* env,
                     ST_SHADOW_STATE shadows, __global uint* queues, __global uint* counters, uint Q, uint NL,
                     uint cur, uint slot, st_path* p) {
  const uint id = ea_entry(scene, NL, slot, p->depth);
  st_shadow e;
  float t0, t1;
  ea_interval(scene, p->o.xyz, p->d.xyz, &t0, &t1);
  e.seg_o = (float4)(p->o.xyz, t0);
  e.seg_d = (float4)(p->d.xyz, t1);
  shadow_store(shadows, Q * NL, id, ST_SHADOW_SEGMENT, &e);
  if (!(t1 > t0) || (scene->max_depth >= 0 && p->depth >= scene->max_depth)) return;
  const uint stream = ST_STREAM_EQUIANGULAR + (uint)p->depth;
  st_rng rng = path_rng(scene, p, stream, 0u);
  const int l = ea_pick(scene, rng_uniform(&rng));
  st_ea_geom g;
  const float u = rng_uniform(&rng);
  if (l < 0 || !ea_geometry(scene->lights[l].position.xyz, e.seg_o, e.seg_d, &g)) return;
  const float t = clamp(g.delta + g.D * tan(mix(g.theta_a, g.theta_b, u)), t0, t1);
  const float q_pea = ea_density(scene, l, e.seg_o, e.seg_d, t);
  if (!(q_pea > 0.0f)) return;
  rng = path_rng(scene, p, stream, 4u); /* draws 2 and 3: the light sample (ea_light_sample) */
  const float4 mask = path_mask(scene, p);
  uint lookups = 0u;
  const float4 weight = ea_unoccluded(scene, grids, env, p, stream, l, t, q_pea, t0, &rng, &lookups);
  counter_add(counters, ST_C_LOOKUPS_SHADOW, lookups);
  if (!(masked_max(fabs(weight), mask) > 0.0f)) return;
  shadow_begin(&e, p->o.xyz, p->d.xyz, t, weight, mask, stream, slot, 0u);
  e.rng_draw = rng_draw_index(&rng);
  e.ea_leg = 1u;
  e.ea_light = (uint)l;
  e.ea_segment = (uint)p->depth;
  shadow_store(shadows, Q * NL, id, ST_SHADOW_BEGUN | ST_SHADOW_EA, &e);
  p->pending += 1;
  queue_push(queues, counters, Q, NL, cur, ST_Q_SHADOW, id);
}

/* Leg 1 of equi-angular entry sh (k_shadow's copy) is done (sh->tr.T: the transmittance from the
 * segment's origin to x): the weight takes it and the entry becomes leg 2, the shadow ray from x to
 * the light along the light sample ea_begin evaluated. Returns 1 when nothing is left to trace (T = 0). */
inline int ea_second_leg(__constant const st_scene* scene, __global const float* env, st_shadow* sh, const st_path* p,
                         float4 mask) {
  const float3 x = sh->o.xyz + sh->t_max * sh->d.xyz;
  float3 wi;
  float pdf_l, t_max;
  ea_light_sample(scene, env, p, sh->stream, (int)sh->ea_light, x, &wi, &pdf_l, &t_max);
  sh->weight *= sh->tr.T;
  sh->ea_leg = 2u;
  if (!(masked_max(fabs(sh->weight), mask) > 0.0f)) {
    sh->tr.T = (float4)(0.0f);
    return 1;
  }
  sh->o = (float4)(x, 0.0f);
  sh->d = (float4)(wi, 0.0f);
  sh->t_max = t_max;
  transmittance_begin(&sh->tr, mask);
  return 0;
}

/* Folds the equi-angular entry of segment s (its place in the ring) into its accumulator (the Ls
 * of the slot's entry n_lights) when it is done; returns 1 while it is still running. */
inline int ea_fold(__constant const st_scene* scene, ST_SHADOW_STATE shadows, __global float4* results, uint Q,
                   uint NL, uint slot, const st_path* p, int s) {
  if (s < 0) return 0;
  const uint id = ea_entry(scene, NL, slot, s), n = Q * NL;
  st_shadow e;
  shadow_load(shadows, n, id, ST_SHADOW_STATUS | ST_SHADOW_EA, &e);
  if (e.state == ST_SHADOW_PENDING) return 1;
  if (e.state == ST_SHADOW_DONE)
    shadow_fold(scene, shadows, n, slot * NL + (uint)scene->n_lights, id, (int)e.ea_segment,
                &results[p->result_index * (uint)scene->result_layers]);
  return 0;
}

#endif
