/* scatter.cl: a real scattering event. Next-event estimation: one shadow ray to every light, or
 * with light sampling "uniform", "power" or "contribution" to one light, weighted by 1 / its
 * probability (a shadow ray to a point or spot light ends at the light: st_shadow.t_max); MIS
 * against phase sampling for lights that phase sampling can hit, the light's pdf
 * taken times select_pmf (1 for all and contribution, whose choice depends on the event: types.h),
 * as k_escape does. Then phase sampling, then Russian roulette on the
 * throughput (from depth 3 on, survival probability min(1, max |beta| over the path's channels),
 * beta divided by it: unbiased; with absorption=weight beta decays by the albedo and this is how
 * paths end). The shadow rays of the last R - 1 bounces (R: the shadow ring, queues.h) may still
 * be running: a path waits here (re-queued) only while an entry of bounce depth - R, whose place this
 * bounce's shadow rays take, is still running; the finished ones are added to their light's
 * accumulator first (queues.h, "shadow-ray entries"). With guiding (features.h), the scattered
 * direction comes from the one-sample mixture of the phase function and the region's guide
 * (guiding.h) at the first scatter events, beta takes f_phase / p_mix and d.w holds p_mix, which
 * the light samples' MIS weights use too; training passes keep the path's last vertices in a ring
 * and credit every later contribution to them (guiding.h, st_guide_vertex). At the ground (a
 * surface vertex, ground.h) the same steps run with the Lambertian f = albedo cos / pi in place of
 * the phase function and cosine sampling in place of phase sampling (no guiding there); a shadow
 * ray that the ground or a sphere light blocks is not traced. */
#include "types.h"
#include "features.h"
#include "rng.h"
#include "sampling.h"
#include "phase.h"
#include "tracking.h"
#include "transmittance.h"
#include "light.h"
#include "ground.h"
#include "guiding.h"
#include "queues.h"
#include "equiangular.h"

/* Folds the finished shadow entries of bounce depth - R (R: the shadow ring) into their lights'
 * accumulators, in a guide training pass crediting them to the ring's earlier vertices (ring not
 * 0); returns 1 while one of them is still running (the path then waits). */
inline int shadows_busy(__constant const st_scene* scene, ST_SHADOW_STATE shadows, __global float4* results, uint Q,
                        uint NL, uint slot, const st_path* p, __global st_guide_vertex* ring) {
  int busy = 0;
  const uint n = Q * NL;
  const int bounce = p->depth - shadow_ring(NL, shadow_lights(scene));
  const float4 lw = ST_HAS_GUIDING && ring ? guide_lane_weights(scene, p) : (float4)(1.0f);
  for (int l = 0; l < scene->n_lights; ++l) {
    const uint e = shadow_entry(slot, NL, shadow_lights(scene), p->depth, l);
    const uint state = shadow_status(shadows, n, e);
    if (state == ST_SHADOW_PENDING) {
      busy = 1;
    } else if (state == ST_SHADOW_DONE) { /* the entry of bounce depth - R (R: the shadow ring) */
      const float4 c = shadow_fold(scene, shadows, n, slot * NL + (uint)l, e, bounce,
                                   &results[p->result_index * (uint)scene->result_layers]);
      if (ST_HAS_GUIDING && ring) guide_credit(ring, 0, bounce - 1, p->depth, c, lw, path_mask(scene, p));
    }
  }
  /* equi-angular sampling: the entry whose place the next segment's takes (equiangular.h) */
  if (ea_on(scene)) busy |= ea_fold(scene, shadows, results, Q, NL, slot, p, bounce + 1);
  return busy;
}

/* The lights next-event estimation samples at this event, [first, *end), and the probability
 * *pick_pmf of a one-light choice (1 when every light is sampled). */
inline int lights_to_sample(__constant const st_scene* scene, __constant const st_medium* m, int ground, float3 wo,
                            float3 x, st_rng* rng, int* end, float* pick_pmf) {
  int first = 0;
  *end = scene->n_lights;
  *pick_pmf = 1.0f;
  if (scene->light_sampling != ST_LIGHT_SAMPLING_ALL && scene->n_lights > 1) {
    if (scene->light_sampling == ST_LIGHT_SAMPLING_CONTRIBUTION) {
      /* at the ground every light is weighed as by an isotropic phase function (unbiased for any weights) */
      first = light_select_contribution(scene, ground ? ST_PHASE_ISOTROPIC : m->phase_type, m->g, m->phase, wo, x,
                                        rng_uniform(rng), pick_pmf);
      *end = first < 0 ? 0 : first + 1;
    } else {
      first = light_select(scene, rng_uniform(rng));
      *end = first + 1;
      *pick_pmf = scene->lights[first].select_pmf;
    }
  }
  return first;
}

/* A camera ray at a shadow catcher (ground.h): with the shadow layer, one light sample per light,
 * its unshadowed estimate E = f Le / pdf (no beta, MIS or albedo) added to ST_RESULT_UNSHADOWED now
 * and a shadow ray that adds E T to ST_RESULT_SHADOW (queues.h shadow_fold); then the path ends. */
inline void shadow_catcher_event(__constant const st_scene* scene, __global const float* env,
                                 ST_SHADOW_STATE shadows, __global uint* queues, __global uint* counters,
                                 __global float4* results, uint Q, uint NL, uint cur, uint slot, st_path* p) {
  if (scene->result_layers > ST_RESULT_UNSHADOWED) {
    st_rng rng = path_rng(scene, p, 0u, p->rng_draw);
    const float4 mask = path_mask(scene, p);
    __global float4* r = &results[p->result_index * (uint)scene->result_layers];
    for (int l = 0; l < scene->n_lights; ++l) {
      float u1 = rng_uniform(&rng), u2 = rng_uniform(&rng);
      float3 wi;
      float pdf_l, t_max;
      float4 Le_over_pdf = light_sample(&scene->lights[l], env, p->o.xyz, u1, u2, &wi, &pdf_l, &t_max, rng.lambda);
      const float4 E = mask * Le_over_pdf * ground_cos_over_pi(wi);
      if (!(masked_max(fabs(E), mask) > 0.0f)) continue;
      r[ST_RESULT_UNSHADOWED] += E;
      if (surface_blocks(scene, p->o.xyz, wi, t_max, 1, l)) continue; /* a sphere light's shadow: T = 0 */
      uint id = shadow_entry(slot, NL, shadow_lights(scene), 0, l);
      st_shadow e;
      shadow_begin(&e, p->o.xyz, wi, t_max, E, mask, 1u + (uint)l, slot, 1u);
      shadow_store(shadows, Q * NL, id, ST_SHADOW_BEGUN, &e);
      p->pending += 1;
      queue_push(queues, counters, Q, NL, cur, ST_Q_SHADOW, id);
    }
    p->rng_draw = rng_draw_index(&rng);
  }
  p->depth = 1; /* k_finish folds the entries of bounce 0 */
  queue_push(queues, counters, Q, NL, cur, ST_Q_FINISH, slot);
}

/* Next-event estimation at the scatter event of *p: one shadow ray per sampled light, weighted by the
 * power heuristic against the density of the scattered direction's sampler (the one-sample mixture
 * where the region guides, alpha > 0; else the phase function, or the ground's cosine lobe). */
inline void scatter_nee(__constant const st_scene* scene, __global const float* env, ST_SHADOW_STATE shadows,
                        __global uint* queues, __global uint* counters, uint Q, uint NL, uint cur, uint slot,
                        st_path* p, st_rng* rng, int ground, float4 albedo, __global const st_guide_region* region,
                        float alpha, float kp) {
  __constant const st_medium* m = &scene->media[ground ? 0 : p->medium];
  const float3 wo = p->d.xyz;
  const float4 mask = path_mask(scene, p);
  int l_end;
  float pick_pmf; /* the probability of a one-light choice */
  const int l_begin = lights_to_sample(scene, m, ground, wo, p->o.xyz, rng, &l_end, &pick_pmf);
  for (int l = l_begin; l < l_end; ++l) {
    __constant const st_light* light = &scene->lights[l];
    float u1 = rng_uniform(rng), u2 = rng_uniform(rng);
    float3 wi;
    float pdf_l, t_max;
    float4 Le_over_pdf = light_sample(light, env, p->o.xyz, u1, u2, &wi, &pdf_l, &t_max, rng->lambda);
    float f = ground ? ground_cos_over_pi(wi) : phase_eval(m->phase_type, m->g, m->phase, dot(wo, wi));
    /* the direction's density under the sampler of the scattered ray: the one-sample mixture
     * with guiding (the same p_mix that k_escape reads from d.w), else the phase function */
    float p_dir = f;
    if (ST_HAS_GUIDING && alpha > 0.0f)
      p_dir = guide_mixture_pdf(alpha, guide_pdf(&region->mix, m->g >= 0.0f ? wo : -wo, kp, wi), f);
    float w = pdf_l > 0.0f ? power_heuristic(light->select_pmf * pdf_l, p_dir) : 1.0f;
    /* in a medium: MIS against the segment's equi-angular sample (equiangular.h) */
    if (ea_on(scene) && p->medium != ST_MEDIUM_GROUND)
      w *= ea_flight_weight(scene, shadows, Q * NL, ea_entry(scene, NL, slot, p->depth), l, p->o.xyz);
    float4 weight = p->beta * mask * Le_over_pdf * (f * w / pick_pmf);
    if (ground) weight *= albedo;
    if (!(masked_max(fabs(weight), mask) > 0.0f)) continue;
    if (surface_blocks(scene, p->o.xyz, wi, t_max, ground, l)) continue;
    uint id = shadow_entry(slot, NL, shadow_lights(scene), p->depth, l);
    st_shadow e;
    shadow_begin(&e, p->o.xyz, wi, t_max, weight, mask, 1u + (uint)p->depth * ST_MAX_LIGHTS + (uint)l, slot, 0u);
    shadow_store(shadows, Q * NL, id, ST_SHADOW_BEGUN, &e);
    p->pending += 1;
    queue_push(queues, counters, Q, NL, cur, ST_Q_SHADOW, id);
  }
}

/* The scattered direction at the path's vertex, its pdf and f: cosine sampling at the ground (beta
 * takes the albedo), the one-sample mixture of phase function and guide (alpha > 0: beta takes
 * f_phase / p_mix, unbiased for any guide), else exact phase sampling (f / pdf = 1, beta unchanged). */
inline float3 scatter_direction(__constant const st_medium* m, __global const st_guide_region* region, float alpha,
                                float kp, int ground, float4 albedo, float3 wo, st_path* p, st_rng* rng, float* pdf,
                                float* f) {
  float3 wi;
  if (ground) {
    float u1 = rng_uniform(rng), u2 = rng_uniform(rng);
    wi = ground_sample_cosine(u1, u2);
    *pdf = *f = ground_cos_over_pi(wi);
    p->beta *= albedo;
  } else if (ST_HAS_GUIDING && alpha > 0.0f) {
    float u0 = rng_uniform(rng), u1 = rng_uniform(rng), u2 = rng_uniform(rng);
    wi = guided_phase_sample(&region->mix, alpha, m->phase_type, m->g, m->phase, wo, u0, u1, u2, rng, pdf, f, kp);
    p->beta *= *pdf > 0.0f ? *f / *pdf : 0.0f;
  } else {
    float u1 = rng_uniform(rng), u2 = rng_uniform(rng);
    wi = phase_sample(m->phase_type, m->g, m->phase, wo, u1, u2, rng, pdf, f);
  }
  return wi;
}

/* Russian roulette on the throughput, from depth 3 on: the queue the path goes to next. */
inline int path_roulette(st_path* p, float4 mask, st_rng* rng) {
  int q = ST_Q_TRACK;
  if (p->depth > 2) {
    float survive = fmin(1.0f, masked_max(fabs(p->beta), mask));
    if (survive < 1.0f) {
      if (rng_uniform(rng) >= survive) q = ST_Q_FINISH;
      else p->beta /= survive;
    }
  }
  return q;
}

ST_STAGE_FUNCTION(scatter) {
  const uint cur = it.cur;
  uint slot = queue_item(queues, Q, NL, cur, ST_Q_SCATTER, gid);
  st_path p;
  path_load(paths, Q, slot, ST_PATH_ALL, &p);
  const int ground = ST_HAS_GROUND && p.medium == ST_MEDIUM_GROUND;
  if (ground && scene->ground.mode == ST_GROUND_SHADOW_CATCHER) {
    if (ST_HAS_GUIDING && guide_training_path(guide, &p)) guide_training_catcher(guide, guide_records, Q, slot, &p);
    shadow_catcher_event(scene, env, shadows, queues, counters, results, Q, NL, cur, slot, &p);
    path_store(paths, Q, slot, ST_PATH_ALL, &p);
    return;
  }
  /* splitting (guiding.h): a waiting child resumes its parent's event at the choice of direction */
  __global st_guide_slot* gs = guide_split_slot(guide, guide_records, slot);
  const int child = gs && gs->split[3];
  if (!child && scene->max_depth >= 0 && p.depth >= scene->max_depth) {
    queue_push(queues, counters, Q, NL, cur, ST_Q_FINISH, slot);
    return;
  }
  const int training = ST_HAS_GUIDING && guide_training_path(guide, &p);
  __global st_guide_vertex* ring = training ? guide_ring(guide_records, (uint)guide->dims[3], Q, slot) : 0;
  if (!child && shadows_busy(scene, shadows, results, Q, NL, slot, &p, ring)) {
    atomic_inc(&counters[ST_C_WAITS]);
    queue_push(queues, counters, Q, NL, cur, ST_Q_SCATTER, slot);
    return;
  }
  if (child) gs->split[3] = 0u;
  else atomic_inc(&counters[ST_C_SCATTER_EVENTS]);
  st_rng rng = path_rng(scene, &p, 0u, p.rng_draw);
  if (ST_HAS_GUIDING) guide_rng_key(&rng, guide, guide_records, slot);
  __constant const st_medium* m = &scene->media[ground ? 0 : p.medium];
  const float4 albedo = ground ? ground_albedo(scene, rng.lambda) : (float4)(1.0f);
  float3 wo = p.d.xyz;
  const float4 mask = path_mask(scene, &p);
  /* guiding: training credits what the path gathered since its last scatter event; the region's
   * mixture and selection probability (alpha 0: plain phase sampling) */
  const float4 lw = training ? guide_lane_weights(scene, &p) : (float4)(1.0f);
  if (training) guide_training_scatter(guide, guide_records, ring, slot, &p, lw, mask);
  __global const st_guide_region* region = 0;
  float alpha = 0.0f, kp = 0.0f; /* kp: the phase lobe of the guide's product (guiding.h) */
  /* not at a ground vertex (the medium index test, not `ground`, which is a constant without a ground) */
  const int in_medium = p.medium != ST_MEDIUM_GROUND;
  if (ST_HAS_GUIDING && guide->origin.w > 0.0f && p.depth < guide->guided_depth && in_medium) {
    region = guide_regions(guide) + guide_region_index(guide, p.o.x, p.o.y, p.o.z);
    alpha = region->alpha;
    kp = guide_phase_kappa(guide, m->phase_type, m->g);
  }
  if (!child) scatter_nee(scene, env, shadows, queues, counters, Q, NL, cur, slot, &p, &rng, ground, albedo, region, alpha, kp);
  /* guided roulette and splitting before the direction is drawn (-1: no estimate here; media only) */
  const int split = gs && !child && in_medium ? guide_rrs(guide, gs, &p, mask, &rng) : -1;
  if (split == 0) { /* the path ends after this event's next-event estimation (its bounce: depth + 1 folds it) */
    p.depth += 1;
    p.rng_draw = rng_draw_index(&rng);
    path_store(paths, Q, slot, ST_PATH_ALL, &p);
    queue_push(queues, counters, Q, NL, cur, ST_Q_FINISH, slot);
    return;
  }
  float pdf, f;
  const float4 beta_in = p.beta;
  const float3 wi = scatter_direction(m, region, alpha, kp, ground, albedo, wo, &p, &rng, &pdf, &f);
  if (training)
    guide_ring_enter(ring, p.depth, p.o.xyz, wi, in_medium ? f : ST_GUIDE_NO_RECORD, beta_in,
                     guide_path_total(shadows, Q * NL, NL, shadow_lights(scene), slot, &p, lw, mask));
  p.d = (float4)(wi, pdf);
  p.o.w = 0.0f;
  p.depth += 1;
  /* the throughput's roulette where guided roulette did not decide (a child was decided at its parent) */
  const int q = split < 0 && !child ? path_roulette(&p, mask, &rng) : ST_Q_TRACK;
  p.rng_draw = rng_draw_index(&rng);
  if (ea_on(scene) && q == ST_Q_TRACK) ea_begin(scene, grids, env, shadows, queues, counters, Q, NL, cur, slot, &p);
  path_store(paths, Q, slot, ST_PATH_ALL, &p);
  queue_push(queues, counters, Q, NL, cur, q, slot);
}
