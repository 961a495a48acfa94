/* walker.h: the trackers' side of the medium interface: their policy over the majorant segments
 * of majorant.h's interval iterator (the gray coefficients of a path's channels, the control and
 * residual components, the spectral coefficients cached once per walk) and the segment walker,
 * the one loop skeleton of free-path sampling (tracking.h) and transmittance (transmittance.h). */
#ifndef SPECTRACK_WALKER_H
#define SPECTRACK_WALKER_H

#include "types.h"
#include "features.h"
#include "rng.h"
#include "sampling.h"
#include "spectrum.h"
#include "medium.h"
#include "majorant.h"

/* ---- the trackers' policy over a majorant segment ---- */

/* Gray extinction (bound) per unit density of medium m over the channels in mask. */
inline float tracker_gray_sigma_t(__constant const st_medium* m, float4 mask) {
  /* a colour grid's extinction bound (medium.h); a colour medium is always chromatic */
  if (medium_has_color(m)) return masked_max(m->sigma_t_maj, mask);
  /* achromatic media: every channel holds the same sum, which is the max over any mask */
  return ST_HAS_CHROMATIC ? masked_max(m->sigma_a + m->sigma_s, mask) : m->sigma_a.x + m->sigma_s.x;
}

/* A majorant segment [t0, t1) as the trackers see it, with its free-path components
 * (docs/estimators.md, 'Decomposition tracking'). Control: the homogeneous part dmin * minorant_scale of every medium,
 * with per-channel coefficients sigma_a_c, sigma_s_c and a gray coefficient mu_bar_c = max over
 * the path's channels of their sum (control collisions can be null for thin channels; no lookup
 * is needed to classify them). Residual: everything else, tracked with the gray coefficient
 * mu_bar_r, which bounds |residual| when the grid's bounds hold; otherwise the |.| probabilities
 * keep it exact. Without decomposition the control is empty and mu_bar_r is the ordinary
 * majorant, the sum over media of dmax * majorant_scale * gray sigma_t. t1 = INFINITY: no
 * medium ahead. */
typedef struct {
  float t0, t1;
  float mu_bar_c, mu_bar_r;
  float4 sigma_a_c, sigma_s_c;
  float density_c[ST_KERNEL_MAX_MEDIA]; /* control density of each medium */
} st_segment;

/* The tracker's view of majorant segment g for a path carrying the channels in mask; sigma_a_l,
 * sigma_s_l: spectral media's coefficients at the path's wavelengths (st_walker), which also make
 * their majorant: the extinction's largest value over the wavelengths the path carries. */
inline st_segment tracker_segment(__constant const st_scene* scene, const st_majorant_segment* g, float4 mask,
                                  const float4* sigma_a_l, const float4* sigma_s_l, int decompose) {
  st_segment s;
  s.t0 = g->t0;
  s.t1 = g->t1;
  s.mu_bar_r = 0.0f;
  s.sigma_a_c = s.sigma_s_c = (float4)(0.0f);
  for (int i = 0; i < ST_KERNEL_MAX_MEDIA; ++i) {
    s.density_c[i] = 0.0f;
    float dmax = g->dmax[i], dmin = g->dmin[i];
    if (i >= scene->n_media || (dmax == 0.0f && dmin == 0.0f)) continue; /* outside, or nothing to add */
    __constant const st_medium* m = &scene->media[i];
    float gray = medium_is_spectral(m) ? fmax(masked_max(sigma_a_l[i] + sigma_s_l[i], mask), 0.0f)
                                       : tracker_gray_sigma_t(m, mask);
    float dmax_s = dmax * m->majorant_scale;
    if (decompose && !medium_has_color(m)) { /* a colour medium has no control (medium.h) */
      float dc = dmin * m->minorant_scale;
      s.density_c[i] = dc;
      s.sigma_a_c += dc * (medium_is_spectral(m) ? sigma_a_l[i] : m->sigma_a);
      s.sigma_s_c += dc * (medium_is_spectral(m) ? sigma_s_l[i] : m->sigma_s);
      /* > 0 whenever the residual can be non-zero, even with scaled (non-bounding) bounds */
      float r = fmax(fmax(dmax_s - dc, m->majorant_scale * (dmax - dmin)), dc - dmin);
      s.mu_bar_r += fmax(r, 0.0f) * gray;
    } else {
      s.mu_bar_r += dmax_s * gray;
    }
  }
  s.mu_bar_c = decompose ? fmax(masked_max(s.sigma_a_c + s.sigma_s_c, mask), 0.0f) : 0.0f;
  return s;
}

/* ---- the segment walker: the one loop skeleton of free-path sampling and transmittance ----
 *
 * Owns the interval iterator, the exponential flights and the iteration budget (after pbrt-v4's
 * SampleT_maj; OpenCL C has no callbacks, so the caller loops on walker_step and runs its own
 * per-collision body). Each step is one iteration of the budget: a flight of rate mu_bar from
 * w->t that ends either at a tentative collision inside the current segment or past its end,
 * where the walk restarts at the next segment (memoryless restart, docs/estimators.md, 'Walking the grid'; segments
 * with mu_bar = 0 are crossed without drawing). Two modes:
 *   ST_WALK_SAMPLE_CONTROL: flights of rate mu_bar_c + mu_bar_r, so tentative collisions of both
 *     components (free-path sampling; the body tells control from residual collisions).
 *   ST_WALK_CONTROL_CLOSED_FORM: flights of rate mu_bar_r (residual ratio tracking); when the
 *     tracker decomposes, w->T_control is the control transmittance exp(-(sigma_a_c + sigma_s_c) dt)
 *     (masked) of each flight, collision or not. */
#define ST_WALK_COLLISION 0 /* a tentative collision at w->t, in segment w->seg */
#define ST_WALK_CROSSED 1   /* the flight passed the segment's end: w->seg is the next segment, w->t its start */
#define ST_WALK_DONE 2      /* no medium ahead: the walk is over at w->t */
#define ST_WALK_BUDGET 3    /* the iteration budget is spent; w->t has no collision pending (resume there) */

#define ST_WALK_SAMPLE_CONTROL 0
#define ST_WALK_CONTROL_CLOSED_FORM 1

typedef struct {
  st_majorant_iterator it; /* the majorant segments (the walker's own) */
  st_majorant_segment maj; /* the current segment's bounds */
  st_segment seg;          /* and the tracker's view of it */
  float t;          /* where the walk is (the float nearest to it: see walker_flight_end) */
  float carry;      /* flight length that t does not hold yet */
  float mu_bar;     /* rate of the flights in seg */
  float4 T_control; /* ST_WALK_CONTROL_CLOSED_FORM with decomposition: the last flight's control transmittance */
  float4 mask;      /* channels of the path */
  /* spectral mode: each spectral medium's coefficients at the path's wavelengths (st_rng.lambda),
   * evaluated once per walk, and their sum (tracker_segment, tracking.h mis_sigma_maj); a colour
   * medium's sigma_s_l is its bound over the colour (walker_begin) */
  float4 sigma_a_l[ST_KERNEL_MAX_MEDIA], sigma_s_l[ST_KERNEL_MAX_MEDIA], sigma_t_l[ST_KERNEL_MAX_MEDIA];
  int decompose, mode, iter, budget;
  int exact;        /* flights below the float spacing of t were met: positions are summed exactly */
  float t_max;      /* where the ray ends (a local light; INFINITY: past every medium) */
  float t_begin;    /* where this call's walk began (walker_refund_empty_crossing) */
} st_walker;

/* The tracker's view of the iterator's current segment. A ray that ends at t_max (local lights,
 * the ground: features.h) clips its segments there: the walk is over (seg.t1 = INFINITY) once it
 * reaches t_max, so no medium beyond the light attenuates it. With t_max = INFINITY nothing
 * changes. */
inline void walker_load_segment(__constant const st_scene* scene, st_walker* w) {
  w->seg = tracker_segment(scene, &w->maj, w->mask, w->sigma_a_l, w->sigma_s_l, w->decompose);
  w->mu_bar = w->mode == ST_WALK_CONTROL_CLOSED_FORM ? w->seg.mu_bar_r : w->seg.mu_bar_c + w->seg.mu_bar_r;
  if ((ST_HAS_LOCAL_LIGHT || ST_HAS_GROUND) && w->seg.t1 > w->t_max)
    w->seg.t1 = (w->t >= w->t_max || isinf(w->seg.t1)) ? INFINITY : w->t_max;
}

/* Starts a walk along the world ray (o, d) from parameter t to t_max (INFINITY: to the end of
 * every medium) with at most `budget` steps. */
inline void walker_begin(__constant const st_scene* scene, __global const float2* maj, st_walker* w, float3 o,
                         float3 d, float t, float t_max, float4 mask, float4 lambda, int decompose, int mode,
                         int budget) {
  majorant_iterator_init(scene, maj, &w->it, o, d, t, &w->maj);
  w->t = t;
  w->t_begin = t;
  w->t_max = t_max;
  w->mask = mask;
  if (ST_HAS_SPECTRAL)
    for (int i = 0; i < ST_KERNEL_MAX_MEDIA; ++i) {
      if (i >= scene->n_media || !medium_is_spectral(&scene->media[i])) continue;
      w->sigma_a_l[i] = medium_sigma_a(&scene->media[i], lambda);
      w->sigma_s_l[i] = medium_sigma_s(&scene->media[i], lambda);
      /* a colour medium's scattering part at its bound (medium.h: 1 for an albedo grid, whose
       * extinction is the colour-free one; the colour spectrum's bound for a scattering grid) */
      if (medium_has_color(&scene->media[i])) w->sigma_s_l[i] *= scene->media[i].sigma_t_maj.x;
      w->sigma_t_l[i] = w->sigma_a_l[i] + w->sigma_s_l[i];
    }
  w->decompose = decompose;
  w->mode = mode;
  w->iter = 0;
  w->budget = budget;
  w->T_control = mask;
  w->carry = 0.0f;
  w->exact = 0;
  walker_load_segment(scene, w);
}

/* Where a flight of length `flight` from w->t ends. Far from the ray origin a flight can be
 * shorter than half the float spacing of t (densities of 1e6 per unit at t ~ 200), so
 * t + flight == t: the flight cannot move t, and without care a walk would repeat the same null
 * collision forever. The walker keeps such a flight's length in w->carry; at the second one in
 * a row it switches the walk to exact summation (two-sum): t is the float nearest to the exact
 * position, w->carry the remainder, and every flight advances the exact position by its full
 * length (to 2^-24 of the flight), so a run of short flights moves t by their total and the
 * walk always progresses. Until then (every flight that moves t on its own, and a single one
 * that does not) the arithmetic is the plain float sum t + flight, so walks whose flights the
 * floats resolve are computed exactly as without the carry. */
inline float walker_flight_end(st_walker* w, float flight) {
  float tc = w->t + flight;
  if (!w->exact) {
    if (tc != w->t || !(flight > 0.0f)) {
      w->carry = 0.0f;
      return tc;
    }
    if (w->carry == 0.0f) { /* a first flight that cannot move t: keep its length */
      w->carry = flight;
      return tc;
    }
    w->exact = 1; /* the second in a row: the flights are below the float spacing of t */
  }
  float s = w->carry + flight;
  tc = w->t + s;
  float moved = tc - w->t;
  w->carry = (w->t - (tc - moved)) + (s - moved); /* t + s == tc + carry exactly */
  return tc;
}

/* A flight passed the current segment's end: the walk restarts exactly there, in the next segment. */
inline int walker_cross(__constant const st_scene* scene, __global const float2* maj, st_walker* w, uint* dda_steps,
                        uint* dda_nonempty) {
  w->t = fmax(w->t, w->seg.t1);
  w->carry = 0.0f;
  majorant_iterator_next(scene, maj, &w->it, &w->maj, dda_steps, dda_nonempty);
  walker_load_segment(scene, w);
  return ST_WALK_CROSSED;
}

/* A segment that ends where the walk stands (a walk begun on a cell's boundary, where the DDA may
 * locate the cell that ends there) is crossed without moving t. When that crossing is the budget's
 * last step and the walk has not moved since walker_begin, it takes none of the budget: otherwise
 * such a walk (a budget of 1, resumed on a boundary) would end its launch where it began, resume
 * there and never finish. Only such a launch, which would repeat itself for ever, changes: every
 * walk that finished before finishes as before, with the same random numbers. */
inline void walker_refund_empty_crossing(st_walker* w) {
  if (!(w->seg.t1 > w->t) && w->iter >= w->budget && !(w->t > w->t_begin)) w->iter -= 1;
}

/* One step of the walk: returns ST_WALK_* (above). DDA steps are added to *dda_steps, those
 * entering a non-empty cell also to *dda_nonempty. */
inline int walker_step(__constant const st_scene* scene, __global const float2* maj, st_walker* w, st_rng* rng,
                       uint* dda_steps, uint* dda_nonempty) {
  if (isinf(w->seg.t1)) return ST_WALK_DONE;
  if (w->iter >= w->budget) return ST_WALK_BUDGET;
  w->iter += 1;
  float tc = w->mu_bar > 0.0f ? walker_flight_end(w, sample_exponential(rng_uniform(rng), w->mu_bar)) : INFINITY;
  if (w->decompose && w->mode == ST_WALK_CONTROL_CLOSED_FORM)
    w->T_control = exp(-(w->seg.sigma_a_c + w->seg.sigma_s_c) * (fmin(tc, w->seg.t1) - w->t)) * w->mask;
  if (tc < w->seg.t1) {
    w->t = tc;
    return ST_WALK_COLLISION;
  }
  walker_refund_empty_crossing(w);
  return walker_cross(scene, maj, w, dda_steps, dda_nonempty);
}

/* One step of a ray march (docs/transmittance.md) in ST_WALK_CONTROL_CLOSED_FORM mode: the same
 * walk as walker_step with the exponential flight replaced by a deterministic one of `s` units of
 * the residual majorant's optical depth (mu_bar_r), so samples can be placed at fixed spacings in
 * majorant optical depth and segments with mu_bar = 0 get none. Returns ST_WALK_COLLISION when
 * the flight ends inside the segment (at w->t; *walked = s), ST_WALK_CROSSED (*walked: the
 * majorant optical depth to the segment's end), ST_WALK_DONE or ST_WALK_BUDGET as walker_step;
 * *tau_control gains the control's optical depth over the step (masked; an optical depth, not its
 * exponential, so that callers can combine it with others before one exp). */
inline int walker_march(__constant const st_scene* scene, __global const float2* maj, st_walker* w, float s,
                        float* walked, float4* tau_control, uint* dda_steps, uint* dda_nonempty) {
  *walked = 0.0f;
  if (isinf(w->seg.t1)) return ST_WALK_DONE;
  if (w->iter >= w->budget) return ST_WALK_BUDGET;
  w->iter += 1;
  float tc = w->mu_bar > 0.0f ? walker_flight_end(w, s / w->mu_bar) : INFINITY;
  if (w->decompose) *tau_control += (w->seg.sigma_a_c + w->seg.sigma_s_c) * (fmin(tc, w->seg.t1) - w->t) * w->mask;
  if (tc < w->seg.t1) {
    *walked = s;
    w->t = tc;
    return ST_WALK_COLLISION;
  }
  if (w->mu_bar > 0.0f) *walked = fmax(w->seg.t1 - w->t, 0.0f) * w->mu_bar;
  walker_refund_empty_crossing(w);
  return walker_cross(scene, maj, w, dda_steps, dda_nonempty);
}

#endif
