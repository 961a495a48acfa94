/* transmittance.h: the transmittance estimators of shadow rays and of the probes, per carried
 * channel: ratio tracking, residual ratio tracking (the decomposition trackers: the control part
 * in closed form) and ray marching (Kettunen et al. 2021), each with Russian roulette on small
 * estimates (transmittance_roulette, the one rule of all three). They walk the majorant segments
 * of majorant.h as free-path sampling (tracking.h) does and resume, like it, when a launch's
 * iteration budget is spent (docs/estimators.md, 'Transmittance estimators'; docs/transmittance.md). */
#ifndef SPECTRACK_TRANSMITTANCE_H
#define SPECTRACK_TRANSMITTANCE_H

#include "types.h"
#include "rng.h"
#include "sampling.h"
#include "medium.h"
#include "majorant.h"
#include "walker.h"
#include "tracking.h"

/* ---- transmittance ---- */

/* Ratio tracking's factor at a tentative collision at p: the residual's null fraction
 * (mu_bar_r - residual sigma_t) / mu_bar_r per carried channel. */
/* The residual component's sigma_t at p: every medium's sigma_a + sigma_s less the segment's control. */
inline float4 residual_sigma_t(__constant const st_scene* scene, __global const uint* grids, const st_walker* w,
                               float3 p, uint* lookups, st_rng* rng) {
  st_medium_point c = medium_sample_point(scene, grids, p, lookups, 1, rng, w->sigma_a_l, w->sigma_s_l);
  return c.sigma_a + c.sigma_s - w->seg.sigma_a_c - w->seg.sigma_s_c;
}

inline float4 ratio_collision_factor(__constant const st_scene* scene, __global const uint* grids,
                                     const st_walker* w, float3 p, float4 mask, uint* lookups, st_rng* rng) {
  float4 residual = residual_sigma_t(scene, grids, w, p, lookups, rng);
  return mask * ((w->seg.mu_bar_r - residual) / w->seg.mu_bar_r);
}

/* The one rule of Russian roulette on a small estimate, m its largest weighted channel (pbrt's
 * constants): returns the probability with which the estimate goes on, 1 when m is not small (no
 * draw), 0.25 when it survives the draw (the caller divides by it) and 0 when it ends. */
inline float roulette_survival(float m, st_rng* rng) {
  if (!(m < 0.05f)) return 1.0f;
  if (m == 0.0f || rng_uniform(rng) < 0.75f) return 0.0f;
  return 0.25f;
}

/* Russian roulette on a small estimate (unbiased: the decision depends on the past only; pbrt's
 * constants). importance: each carried channel's share of what the estimate is for, in [0, 1]
 * (a shadow ray: its weight over the weight's largest channel; the mask for transmittance itself),
 * so that a channel whose T stays high but whose weight is small (the blue of a path that has lost
 * its blue to albedo) does not keep a ray going. Returns 0 when the estimate ends (then *T = 0). */
inline int transmittance_roulette(float4* T, float4 mask, float4 importance, st_rng* rng) {
  float q = roulette_survival(masked_max(fabs(*T) * importance, mask), rng);
  if (q == 0.0f) {
    *T = (float4)(0.0f);
    return 0;
  }
  if (q < 1.0f) *T /= q;
  return 1;
}

/* Transmittance along (o, d) from *t to t_max (INFINITY: the end of every medium), per channel: ratio tracking,
 * or residual ratio tracking for the decomposition trackers (the control part exp(-mu_c dt) in
 * closed form, ratio tracking of the residual with mu_bar_r). Russian roulette after every
 * update of the estimate (also after the closed-form control factor, which can make T tiny
 * without any lookup). Returns 1 when finished, 0 when the budget is spent (call again from *t). */
inline int ratio_track(__constant const st_scene* scene, __global const uint* grids, __global const float2* maj,
                       float3 o, float3 d, float t_max, float* t, float4* T, float4 mask, float4 importance, st_rng* rng,
                       int budget, st_track_stats* st) {
  st_walker w;
  walker_begin(scene, maj, &w, o, d, *t, t_max, mask, rng->lambda, tracker_decomposes(scene), ST_WALK_CONTROL_CLOSED_FORM,
               budget);
  for (;;) {
    int step = walker_step(scene, maj, &w, rng, &st->dda_steps, &st->dda_nonempty);
    *t = w.t;
    if (step == ST_WALK_DONE) return 1;
    if (step == ST_WALK_BUDGET) return 0;
    if (w.decompose) *T *= w.T_control;
    if (step == ST_WALK_COLLISION) *T *= ratio_collision_factor(scene, grids, &w, o + w.t * d, mask, &st->lookups, rng);
    if (!transmittance_roulette(T, mask, importance, rng)) return 1;
  }
}

/* ---- ray-marching transmittance (Kettunen et al. 2021; docs/transmittance.md) ----
 *
 * T = exp(-tau_ctrl) exp(-tau_r): the control part (decomposition trackers) in closed form, the
 * residual optical depth tau_r = integral of the residual sigma_t, whose majorant is mu_bar_r
 * (the ordinary majorant and all of sigma_t without decomposition). In majorant optical depth s,
 * tau_r = integral over [0, tau_maj] of f = residual sigma_t / mu_bar_r. With an expansion point
 * tau_c, exp(-tau_r) = exp(-tau_c) sum_k (tau_c - tau_r)^k / k!; term k is estimated without bias
 * by exp(-tau_c) X_1 ... X_k / k! with independent X_j of mean tau_c - tau_r, and the series is
 * truncated by Russian roulette (each term divided by the probability of reaching it).
 *   pass 0, one walk: the pilot, samples every pilot_spacing of s from a random offset (its
 *     first one always inside the first non-empty segment), gives tau_maj, the control's optical
 *     depth tau_ctrl, fbar = mean f and tau_c = max(tau_maj fbar, -tau_ctrl); at the same time an
 *     independent comb (spacing h = march_spacing, its own offset: E[h sum g(s_i)] = integral g ds
 *     for any g) gives X_1 = (tau_c - tau_maj fbar) + h sum_i (fbar - f(s_i)), whose mean given
 *     the pilot is tau_c - tau_r. Where f is constant X_1 = 0 (up to rounding): no variance.
 *     Russian roulette on the running estimate keeps dense rays cheap (ratio tracking's constants).
 *   pass k >= 2 (reached with probability q = min(1, max_c |P_c| / P_0,c), P the last term; q = 0
 *     only when every later term is 0): one walk with N = max(ST_MARCH_MIN_SAMPLES,
 *     ceil(tau_maj / h)) samples spaced tau_maj / N (stratified), X_k = tau_c - (tau_maj / N) sum f.
 * Unbiased: given the pilot the X_j are independent with mean tau_c - tau_r, and every roulette
 * depends on the past only. The estimate is a weighted sum: it can leave [0, 1]. */
#define ST_MARCH_MIN_SAMPLES 2.0f

/* Starts a transmittance estimate carrying the channels in mask. */
inline void transmittance_begin(st_trans* tr, float4 mask) {
  tr->T = mask;
  tr->tau_c = tr->P = tr->S = tr->acc = tr->acc1 = (float4)(0.0f);
  tr->s_left = tr->s_left1 = -1.0f;
  tr->tau_maj = 0.0f;
  tr->count = tr->count1 = 0u;
  tr->pass = 0;
  tr->pilot_met = tr->pad0 = 0;
}

/* f = residual sigma_t / mu_bar_r at p, per carried channel. */
inline float4 march_sample(__constant const st_scene* scene, __global const uint* grids, const st_walker* w, float3 p,
                           float4 mask, uint* lookups, st_rng* rng) {
  return mask * (residual_sigma_t(scene, grids, w, p, lookups, rng) / w->seg.mu_bar_r);
}

/* The end of a walk of ray_march_transmittance: the pilot's P_0 and X_1 (pass 0) or the next
 * term's factor (pass k), then the roulette that decides whether one more term is estimated.
 * Returns 1 when the estimate is finished (in tr->T), 0 when another walk follows. */
inline int march_end_of_walk(st_trans* tr, float4 mask, float h, float spacing, st_rng* rng) {
  if (tr->pass == 0) {
    float4 fbar = tr->count > 0u ? tr->acc / (float)tr->count : (float4)(0.0f);
    /* the expansion point: the ratio form, kept >= -tau_ctrl (the whole optical depth is >= 0),
     * so P_0 = exp(-(tau_ctrl + tau_c)) <= the roulette factor: no overflow */
    tr->tau_c = fmax(tr->tau_maj * fbar, -tr->S);
    tr->T = tr->P * exp(-(tr->S + tr->tau_c)) * mask; /* P_0 */
    tr->S = tr->T;
    if (!(tr->tau_maj > 0.0f)) return 1; /* no residual anywhere on the ray: P_0 is exact */
    /* X_1 = tau_c - (an unbiased estimate of tau_r given the pilot): h sum f over the first
     * estimate's comb, plus the control variate fbar (tau_maj - h count1), of mean 0 */
    float4 X = (tr->tau_c - tr->tau_maj * fbar) + h * ((float)tr->count1 * fbar - tr->acc1);
    tr->P = tr->T * X * mask;
    tr->pass = 1;
  } else {
    tr->P *= (tr->tau_c - spacing * tr->acc) * (mask / (float)tr->pass);
  }
  tr->S += tr->P;
  float4 E = fabs(tr->T);
  float q = fmin(masked_max(select((float4)(0.0f), fabs(tr->P) / E, E > 0.0f), mask), 1.0f);
  if (!(q > 0.0f) || rng_uniform(rng) >= q) {
    tr->T = tr->S;
    return 1;
  }
  tr->P /= q;
  tr->pass += 1;
  tr->s_left = -1.0f;
  return 0;
}

/* Runs the estimate of tr along (o, d) up to t_max (every walk starts at t = 0) for at most `budget` steps
 * in all. Returns 1 when it is finished (the estimate in tr->T), 0 when the budget is spent (call
 * again: *t and tr hold where it is). */
inline int ray_march_transmittance(__constant const st_scene* scene, __global const uint* grids,
                                   __global const float2* maj, float3 o, float3 d, float t_max, float* t,
                                   st_trans* tr, float4 mask, float4 importance, st_rng* rng, int budget,
                                   st_track_stats* st) {
  int left = budget;
  const float h = scene->march_spacing;
  for (;;) {
    const int first = tr->pass == 0;
    float spacing = first ? scene->pilot_spacing
                          : tr->tau_maj / fmax(ST_MARCH_MIN_SAMPLES, ceil(tr->tau_maj / h));
    if (tr->s_left < 0.0f) { /* a walk starts */
      tr->s_left = rng_uniform(rng) * spacing;
      tr->acc = (float4)(0.0f);
      if (first) {
        tr->s_left1 = rng_uniform(rng) * h;
        tr->P = mask; /* the pilot's roulette factor */
      }
      *t = 0.0f;
    }
    st_walker w;
    walker_begin(scene, maj, &w, o, d, *t, t_max, mask, rng->lambda, tracker_decomposes(scene),
                 ST_WALK_CONTROL_CLOSED_FORM, left);
    float4 tau_none = (float4)(0.0f);
    for (;;) {
      if (first && !tr->pilot_met && w.mu_bar > 0.0f) { /* the first non-empty segment: the pilot samples it */
        float rest = (w.seg.t1 - w.t) * w.mu_bar;
        if (tr->s_left > rest) tr->s_left = rng_uniform(rng) * rest;
        tr->pilot_met = 1; /* decided once (saved across launches) */
      }
      float s = first ? fmin(tr->s_left, tr->s_left1) : tr->s_left;
      float walked;
      /* pass 0: tr->S holds the control's optical depth so far */
      int step = walker_march(scene, maj, &w, s, &walked, first ? &tr->S : &tau_none, &st->dda_steps,
                              &st->dda_nonempty);
      if (step == ST_WALK_BUDGET) {
        *t = w.t;
        return 0;
      }
      if (step == ST_WALK_DONE) break;
      int hit = step == ST_WALK_COLLISION && tr->s_left <= s;
      int hit1 = first && step == ST_WALK_COLLISION && tr->s_left1 <= s;
      if (hit || hit1) {
        float4 f = march_sample(scene, grids, &w, o + w.t * d, mask, &st->lookups, rng);
        if (hit) tr->acc += f, tr->count += first ? 1u : 0u;
        if (hit1) tr->acc1 += f, tr->count1 += 1u;
      }
      tr->s_left = hit ? spacing : fmax(tr->s_left - walked, 0.0f);
      if (!first) continue;
      tr->s_left1 = hit1 ? h : fmax(tr->s_left1 - walked, 0.0f);
      tr->tau_maj += walked;
      /* Russian roulette on the pilot's running estimate (exp of the control's and the ratio-form
       * residual optical depth so far, clamped at 0 so it cannot overflow; ratio tracking's
       * constants), its factor kept in P. Any rule that looks only at the past is unbiased. */
      float4 tau_so_far = tr->count > 0u ? tr->tau_maj * tr->acc / (float)tr->count : (float4)(0.0f);
      float q = roulette_survival(masked_max(tr->P * exp(-fmax(tr->S + tau_so_far, 0.0f)) * importance, mask), rng);
      if (q == 0.0f) {
        tr->T = (float4)(0.0f);
        return 1;
      }
      if (q < 1.0f) tr->P /= q;
    }
    left -= w.iter;
    if (march_end_of_walk(tr, mask, h, spacing, rng)) return 1;
    *t = 0.0f;
    if (left <= 0) return 0;
  }
}

/* The scene's transmittance estimator along (o, d) from t = 0 (the ray's origin; *t is where a
 * resumed estimate is) to t_max (INFINITY: the end of every medium), per carried channel; tr from transmittance_begin; importance: the
 * channels' weights for Russian roulette (transmittance_roulette). Returns 1 when finished (the
 * estimate in tr->T), 0 when the budget is spent (call again). */
inline int transmittance_estimate(__constant const st_scene* scene, __global const uint* grids,
                                  __global const float2* maj, float3 o, float3 d, float t_max, float* t,
                                  st_trans* tr, float4 mask, float4 importance, st_rng* rng, int budget,
                                  st_track_stats* st) {
  if (ST_HAS_RAY_MARCHING && scene->transmittance == ST_TRANSMITTANCE_RAY_MARCHING)
    return ray_march_transmittance(scene, grids, maj, o, d, t_max, t, tr, mask, importance, rng, budget, st);
  float4 T = tr->T;
  int done = ratio_track(scene, grids, maj, o, d, t_max, t, &T, mask, importance, rng, budget, st);
  tr->T = T;
  return done;
}

#endif
