/* tracking.h: the per-collision bodies of free-path sampling (transmittance: transmittance.h), on the integral
 * formulation of null-collision algorithms (docs/estimators.md, 'The integral formulation'); the loop around them (segments,
 * exponential flights, iteration budget) is the walker of walker.h.
 *
 * One routine serves every tracker. Per majorant segment a gray free-path coefficient mu_bar is
 * used; at each tentative collision the event (absorption, scattering, null) is chosen with
 * probabilities P / p_sum, P = (P_a, P_s, P_n) from the tracker's scheme and p_sum their sum,
 * and the path weight beta is multiplied by mu / (mu_bar P / p_sum) of the event. The trackers
 * are choices of mu_bar's channel set (the path's mask), of the scheme and of the decomposition:
 *   delta-per-channel: mask = one channel, beta = e_c      -> analog delta tracking of channel c
 *   delta:             mask = rgb, achromatic media, max    -> analog delta tracking
 *   spectral:          mask = rgb, the chosen scheme (max, average, history-max, history-average)
 *   decomposition, spectral-decomposition: the same with control and residual components
 *                      (docs/estimators.md, 'Decomposition tracking')
 * The |.| in the probabilities keeps every tracker unbiased when a majorant does not bound
 * (negative null coefficient: weighted tracking, docs/estimators.md, 'Bounds that do not bound'); with a bounding majorant
 * the delta trackers' weights are exactly analog.
 * Emission is scored at absorption events only: beta * mu_a Le / (mu_bar P_a / p_sum)
 * (docs/estimators.md, 'Absorption modes'), in the absorption=event mode; in the absorption=weight mode (paper 5.1.3)
 * there are no absorption events and emission is a collision estimator at every real collision
 * (see "absorption as a weight" below). Every walk has an iteration budget; when it is spent the routine returns
 * ST_EV_BUDGET (ratio_track: 0) with t at a point where no collision is pending, and the caller
 * re-queues the item (never a cap that biases).
 */
#ifndef SPECTRACK_TRACKING_H
#define SPECTRACK_TRACKING_H

#include "types.h"
#include "features.h"
#include "rng.h"
#include "sampling.h"
#include "spectrum.h"
#include "medium.h"
#include "majorant.h"
#include "walker.h"

#define ST_EV_ESCAPE 0
#define ST_EV_SCATTER 1
#define ST_EV_ABSORB 2
#define ST_EV_BUDGET 3

typedef struct {
  uint lookups, emission_lookups, real, nulls, control, residual, dda_steps, dda_nonempty;
  float max_beta;
} st_track_stats;

inline void track_stats_clear(st_track_stats* s) {
  s->lookups = s->emission_lookups = s->real = s->nulls = s->control = s->residual = s->dda_steps = s->dda_nonempty = 0u;
  s->max_beta = 0.0f;
}

/* The probability scheme a tracker uses: the chosen one for the spectral trackers, analog
 * (channel max, which is exact for one channel or achromatic media) for the others. */
inline int tracker_scheme(__constant const st_scene* scene) {
  return st_tracker_uses_scheme(scene->tracker) ? scene->scheme : ST_SCHEME_MAX;
}

inline int tracker_decomposes(__constant const st_scene* scene) {
  return ST_HAS_DECOMPOSITION && st_tracker_decomposes(scene->tracker);
}

inline float scheme_reduce(int scheme, float4 v, float4 mask) {
  return (scheme == ST_SCHEME_MAX || scheme == ST_SCHEME_HISTORY_MAX) ? masked_max(v, mask) : masked_avg(v, mask);
}

/* The scheme's un-normalised event probabilities P = (P_a, P_s, P_n) for the coefficients of
 * absorption, scattering and null collisions: a reduction over the carried channels of
 * |sigma| weighted by 1 or, for the history-aware schemes, by |beta|. */
inline float3 event_values(int scheme, float4 beta, float4 mask, float4 sigma_a, float4 sigma_s, float4 sigma_n) {
  int history = scheme == ST_SCHEME_HISTORY_MAX || scheme == ST_SCHEME_HISTORY_AVERAGE;
  float4 weight = history ? fabs(beta) * mask : mask;
  return (float3)(scheme_reduce(scheme, weight * fabs(sigma_a), mask), scheme_reduce(scheme, weight * fabs(sigma_s), mask),
                  scheme_reduce(scheme, weight * fabs(sigma_n), mask));
}

/* ---- absorption as a weight (scene->absorption == ST_ABSORPTION_WEIGHT; paper 5.1.3) ----
 *
 * Event probabilities: P = (0, P_r, P_n) with P_r = reduce(w |sigma_a| + w |sigma_s|) (= the
 * scheme's reduction of w sigma_t for a physical component, whose coefficients are >= 0; the sum
 * of the two magnitudes keeps P_r > 0 wherever a residual component has sigma_a != 0 or
 * sigma_s != 0 even if they cancel), P_n = reduce(w |sigma_n|), w = 1 or |beta| (history schemes).
 *
 * Unbiasedness. The integral formulation (docs/estimators.md) at a tentative collision x with the
 * component's gray mu_bar is
 *   L(x) = [sigma_a Le + sigma_s (f_p * L_s) + sigma_n L(x')] / mu_bar   (per channel, then * beta).
 * We sample "real" with probability P_r / p_sum and "null" with P_n / p_sum. On "real" the path
 * scores beta sigma_a Le * p_sum / (mu_bar P_r) (the emission term, below) and continues with
 * beta' = beta sigma_s_k (1 / p_k) p_sum / (mu_bar P_r) (p_k: the choice of the scattering medium
 * k in proportion to |beta sigma_s,k|, whose expectation over k gives sigma_s); on "null",
 * beta' = beta sigma_n p_sum / (mu_bar P_n). Each term's expectation is its term of L(x), so the
 * estimator is unbiased whenever P_r > 0 where sigma_a or sigma_s != 0 and P_n > 0 where
 * sigma_n != 0, which the magnitudes above guarantee, bounding majorant or not (a negative sigma_n
 * only flips the sign of beta). The absorption term sigma_a L = 0 that the event mode samples is
 * simply not sampled: the path carries the albedo sigma_s / sigma_t instead of ending.
 *
 * Emission as a collision estimator. The score at a real collision is
 *   beta sigma_a Le / (mu_bar P_r / p_sum)   (before beta is updated),
 * the same formula as the event mode's absorption score with P_a replaced by P_r: it uses the
 * real collision's probability, so the absorption part of every real collision contributes,
 * not only the fraction sigma_a / sigma_t of them that the event mode turns into absorptions.
 * With decomposition the component's own coefficients (option A, docs/estimators.md, 'Decomposition tracking') and density
 * parts are used, so a control collision scores the control's sigma_a Le with the control's
 * density parts, and needs no density lookup (Le of a gridded emission still reads its grid).
 *
 * The throughput bound with history-average (w = |beta|, reduce = average over the n carried
 * channels, a bounding majorant so sigma_n >= 0 and sigma_t + sigma_n = mu_bar per channel):
 *   p_sum = avg(|beta| sigma_t) + avg(|beta| sigma_n) = mu_bar avg|beta|.
 *   real:  sum_c |beta'_c| = sum_c |beta_c| sigma_s,k,c (1/p_k) avg|beta| / avg(|beta| sigma_t);
 *          with 1/p_k = sum_j q_j / q_k, q_j = avg(|beta| sigma_s,j) this is
 *          n avg(|beta| sigma_s) avg|beta| / avg(|beta| sigma_t) <= n avg|beta| = sum_c |beta_c|
 *          (sigma_s <= sigma_t per channel);
 *   null:  sum_c |beta'_c| = n avg(|beta| sigma_n) avg|beta| / avg(|beta| sigma_n) = sum_c |beta_c|.
 * So the sum of the channel weights never grows along a path; it starts at n = 3 for rgb, 4 in
 * spectral mode (and Russian roulette in scatter.cl divides by min(1, max_c |beta_c|), which leaves
 * max_c |beta_c| <= 1 when it applies), so every component of beta stays <= n: max_throughput <= 3
 * holds in both absorption modes for rgb (tests/test_estimators.cpp HistoryAverageBoundsThroughputByThree*).
 *
 * Paths end by Russian roulette (scatter.cl): after the phase sample from depth 3 on, the path
 * survives with probability q = min(1, max_c |beta_c|) over its carried channels and beta /= q
 * (unbiased). In the event mode the analog trackers' beta stays 1, so their roulette never fires. */

inline int absorption_as_weight(__constant const st_scene* scene) { return scene->absorption == ST_ABSORPTION_WEIGHT; }

/* ---- free-path sampling ---- */

/* The component a tentative collision belongs to, with its coefficients at the collision:
 * sigma_a, sigma_s, the null coefficient sigma_n = mu_bar - sigma_a - sigma_s per channel, the
 * component's gray coefficient mu_bar and each medium's part of the component's density. */
typedef struct {
  float4 sigma_a, sigma_s, sigma_n;
  float mu_bar;
  float density[ST_KERNEL_MAX_MEDIA];
  float4 tint[ST_KERNEL_MAX_MEDIA]; /* each colour medium's C at the collision (medium.h; else 1) */
} st_collision;

/* A tentative collision at p belongs to the control component with probability
 * mu_bar_c / (mu_bar_c + mu_bar_r) (the race of two exponential flights) and is classified with
 * that component's own coefficients (option A of docs/estimators.md, 'Decomposition tracking'): a control collision needs
 * no lookup, a residual one looks the density up and subtracts the control. */
inline st_collision collision_component(__constant const st_scene* scene, __global const uint* grids,
                                        const st_walker* w, float3 p, st_rng* rng, st_track_stats* st) {
  const st_segment* seg = &w->seg;
  st_collision c;
  if (seg->mu_bar_c > 0.0f && rng_uniform(rng) * w->mu_bar < seg->mu_bar_c) {
    c.sigma_a = seg->sigma_a_c; /* control collision: constants, no density lookup */
    c.sigma_s = seg->sigma_s_c;
    c.mu_bar = seg->mu_bar_c;
    for (int i = 0; i < ST_KERNEL_MAX_MEDIA; ++i) {
      c.density[i] = seg->density_c[i]; /* 0 for colour media, which have no control */
      c.tint[i] = (float4)(1.0f);
    }
    st->control += 1u;
  } else {
    st_medium_point k = medium_sample_point(scene, grids, p, &st->lookups, 0, rng, w->sigma_a_l, w->sigma_s_l);
    c.sigma_a = k.sigma_a - seg->sigma_a_c;
    c.sigma_s = k.sigma_s - seg->sigma_s_c;
    c.mu_bar = seg->mu_bar_r;
    for (int i = 0; i < ST_KERNEL_MAX_MEDIA; ++i) {
      c.density[i] = k.density[i] - seg->density_c[i];
      c.tint[i] = k.tint[i];
    }
    if (w->decompose) st->residual += 1u;
  }
  c.sigma_n = c.mu_bar - c.sigma_a - c.sigma_s;
  return c;
}

/* sigma_a Le at p at time t, summed over the emissive media that have a part of the collision's density. */
inline float4 absorbed_emission(__constant const st_scene* scene, __global const uint* grids, const st_collision* c,
                                float3 p, float t, uint* lookups, float4 lambda) {
  float4 mua_Le = (float4)(0.0f);
  for (int i = 0; i < ST_KERNEL_MAX_MEDIA; ++i) {
    if (i >= scene->n_media || c->density[i] == 0.0f) continue;
    __constant const st_medium* m = &scene->media[i];
    if (!m->emissive) continue;
    float4 sigma_a, sigma_s;
    medium_unit_coeffs(m, grids, c->tint[i], lambda, &sigma_a, &sigma_s);
    mua_Le += c->density[i] * sigma_a * medium_Le(m, grids, p, t, lookups, lambda);
  }
  return mua_Le;
}

/* The medium whose phase function applies at a scattering collision, chosen in proportion to
 * |beta * sigma_s| of each medium's part of the collision (averaged over the carried channels);
 * with one medium, medium 0. Sets *sigma_s_k to that part's scattering coefficient and *inv_p to
 * the reciprocal of the choice's probability; returns -1 when no medium scatters any carried
 * channel. */
inline int choose_scattering_medium(__constant const st_scene* scene, __global const uint* grids, const st_collision* c,
                                    float4 beta, float4 mask, st_rng* rng, float4* sigma_s_k, float* inv_p) {
  *sigma_s_k = c->sigma_s;
  *inv_p = 1.0f;
  if (!(ST_HAS_MULTI_MEDIUM && scene->n_media > 1)) return 0;
  float q[ST_KERNEL_MAX_MEDIA];
  float q_sum = 0.0f;
  for (int i = 0; i < ST_KERNEL_MAX_MEDIA; ++i) {
    q[i] = 0.0f;
    if (i >= scene->n_media) continue;
    float4 sigma_a, sigma_s;
    medium_unit_coeffs(&scene->media[i], grids, c->tint[i], rng->lambda, &sigma_a, &sigma_s);
    q[i] = masked_avg(fabs(beta * c->density[i] * sigma_s), mask);
    q_sum += q[i];
  }
  float xi = rng_uniform(rng) * q_sum;
  int k = -1;
  for (int i = 0; i < ST_KERNEL_MAX_MEDIA; ++i) {
    if (i >= scene->n_media || q[i] <= 0.0f) continue;
    k = i;
    if (xi < q[i]) break;
    xi -= q[i];
  }
  if (k < 0) return -1;
  float4 sigma_a;
  medium_unit_coeffs(&scene->media[k], grids, c->tint[k], rng->lambda, &sigma_a, sigma_s_k);
  *sigma_s_k *= c->density[k];
  *inv_p = q_sum / q[k];
  return k;
}

#define ST_EV_NULL 4 /* internal to track_free_path: a null collision, the walk goes on */

/* The body of free-path sampling at a tentative collision at p: the event (absorption,
 * scattering, null) is chosen with probabilities P / p_sum, P = (P_a, P_s, P_n) the scheme's
 * un-normalised event probabilities, and beta is multiplied by mu / (mu_bar P / p_sum) of the
 * event (absorption=weight: P_a = 0 and emission scored at the real collision, see above).
 * Returns ST_EV_ABSORB (emission scored into *L; beta = 0 when nothing is left to carry),
 * ST_EV_SCATTER (*medium: the medium whose phase function applies) or ST_EV_NULL. */
inline int free_path_collision(__constant const st_scene* scene, __global const uint* grids, const st_walker* w,
                               float3 p, int scheme, float4* beta, float4 mask, float4* L, int* medium, st_rng* rng,
                               st_track_stats* st) {
  st_collision c = collision_component(scene, grids, w, p, rng, st);
  int weighted = absorption_as_weight(scene);
  float3 P = weighted ? event_values(scheme, *beta, mask, (float4)(0.0f), fabs(c.sigma_a) + fabs(c.sigma_s), c.sigma_n)
                      : event_values(scheme, *beta, mask, c.sigma_a, c.sigma_s, c.sigma_n);
  float p_sum = P.x + P.y + P.z;
  if (!(p_sum > 0.0f)) { /* nothing left to carry on any channel */
    *beta = (float4)(0.0f);
    return ST_EV_ABSORB;
  }
  float xi = rng_uniform(rng) * p_sum;
  if (xi < P.x) {
    if (ST_HAS_EMISSION) {
      float4 mua_Le = absorbed_emission(scene, grids, &c, p, rng->time, &st->emission_lookups, rng->lambda);
      *L += *beta * mask * mua_Le * (p_sum / (c.mu_bar * P.x));
    }
    st->real += 1u;
    return ST_EV_ABSORB;
  }
  if (xi < P.x + P.y) {
    if (ST_HAS_EMISSION && weighted) { /* emission as a collision estimator at the real collision */
      float4 mua_Le = absorbed_emission(scene, grids, &c, p, rng->time, &st->emission_lookups, rng->lambda);
      *L += *beta * mask * mua_Le * (p_sum / (c.mu_bar * P.y));
    }
    float4 sigma_s_k;
    float inv_p;
    int k = choose_scattering_medium(scene, grids, &c, *beta, mask, rng, &sigma_s_k, &inv_p);
    if (k < 0) {
      *beta = (float4)(0.0f);
      st->real += weighted ? 1u : 0u;
      return ST_EV_ABSORB;
    }
    *beta *= sigma_s_k * inv_p * (p_sum / (c.mu_bar * P.y));
    *medium = k;
    st->real += 1u;
    if (weighted && !(masked_max(fabs(*beta), mask) > 0.0f)) { /* nothing scatters: the path ends here */
      *beta = (float4)(0.0f);
      return ST_EV_ABSORB;
    }
    st->max_beta = fmax(st->max_beta, masked_max(fabs(*beta), mask));
    return ST_EV_SCATTER;
  }
  *beta *= c.sigma_n * (p_sum / (c.mu_bar * P.z));
  st->nulls += 1u;
  st->max_beta = fmax(st->max_beta, masked_max(fabs(*beta), mask));
  return ST_EV_NULL;
}

/* Samples the next real collision along (o, d) from *t up to t_max (the ground's distance, else
 * INFINITY). On ST_EV_SCATTER, *t is the collision,
 * beta carries the scattering weight and *medium the medium whose phase function applies. On
 * ST_EV_ABSORB the emission score has been added to *L. On ST_EV_ESCAPE the ray left every
 * medium (or reached t_max). On ST_EV_BUDGET, call again from *t. */
inline int track_free_path(__constant const st_scene* scene, __global const uint* grids, __global const float2* maj,
                           float3 o, float3 d, float* t, float t_max, float4* beta, float4 mask, float4* L, int* medium,
                           st_rng* rng, int budget, st_track_stats* st) {
  st_walker w;
  walker_begin(scene, maj, &w, o, d, *t, t_max, mask, rng->lambda, tracker_decomposes(scene), ST_WALK_SAMPLE_CONTROL,
               budget);
  int scheme = tracker_scheme(scene);
  for (;;) {
    int step = walker_step(scene, maj, &w, rng, &st->dda_steps, &st->dda_nonempty);
    if (step == ST_WALK_CROSSED) continue;
    *t = w.t;
    if (step == ST_WALK_DONE) return ST_EV_ESCAPE;
    if (step == ST_WALK_BUDGET) return ST_EV_BUDGET;
    int ev = free_path_collision(scene, grids, &w, o + w.t * d, scheme, beta, mask, L, medium, rng, st);
    if (ev != ST_EV_NULL) return ev;
  }
}

/* ---- spectral MIS (tracker spectral-mis; Miller, Georgiev and Jarosz 2019, pbrt-v4's volpath) ----
 *
 * Each path draws a hero channel h uniformly (raygen.cl) and samples its free paths as delta
 * tracking of channel h would: flights of rate sigma_maj,h (the segment's majorant of channel h),
 * and at a tentative collision the event with probabilities P_e,h / S_h, where per channel c
 *   absorption=event:  P_a = |sigma_a|, P_s = |sigma_s|, P_n = |sigma_n|,
 *   absorption=weight: P_a = 0, P_s = |sigma_a| + |sigma_s|, P_n = |sigma_n|,
 * sigma_n = sigma_maj - sigma_a - sigma_s per channel and S = P_a + P_s + P_n (= sigma_maj when the
 * majorant bounds; the |.| keep non-bounding majorants exact, as in the other trackers). Every
 * channel's estimate uses its own majorant: the integral formulation holds for any majorant, so
 * the path throughput f_c of channel c carries T_maj,c = exp(-sigma_maj,c dt) per flight and
 * sigma_s,c or sigma_n,c per event, and technique c (hero c) has the path pdf p_c, the product of
 * T_maj,c per flight and sigma_maj,c P_e,c / S_c per event. The one-sample MIS with the balance
 * heuristic over the n techniques (n lanes: 3 channels, or 4 wavelengths in spectral mode), each
 * chosen with probability 1/n, scores
 *   f_c / ((1/n) sum_k p_k) = (f_c / p_h) / mean_k (p_k / p_h),
 * which is unbiased for every channel c whenever some technique can make each path f_c != 0 gives
 * (the hero always can, so every path the render can make is covered).
 *
 * State: beta = f / p_h and r_u = p_k / p_h (pbrt's names), both scaled by the same factor after
 * every update so that mean(r_u) = 1. The score beta / mean(r_u) does not change under a common
 * factor, so with that scaling beta IS the MIS-weighted throughput: next-event estimation, escape,
 * Russian roulette and max_throughput (scatter.cl, shade.cl) use it unchanged. With absorption
 * events and bounding majorants beta <= n: f_c / mean p_k <= n f_c / p_c, and f_c / p_c = 1 for
 * channel c's own (analog) delta tracking. With absorption as a weight f_c / p_c starts as the
 * product of albedos <= 1, but Russian roulette (scatter.cl, on beta as pbrt-v4 does) divides every
 * channel by the survival probability q = max_c beta_c, which can leave f_c / p_c > 1 on a
 * channel whose own pdf was small; a later shift of the pdfs towards that channel then takes its
 * beta above 3 (3.75 seen in tests/test_estimators.cpp's strongly chromatic scene): no bound of 3
 * is claimed in that mode.
 *
 * Emission is a collision estimator at every tentative collision (as pbrt-v4): a vertex there has
 * the pdf T_maj,k sigma_maj,k under technique k, so the score is beta sigma_a Le / mean(r_u sigma_maj)
 * (before the event's update); an absorption event then scores nothing more (it ends the path).
 * The scattering medium of several overlapping ones is chosen in proportion to the mean over the
 * channels of density_k sigma_s,k (the same for every technique, so it cancels in r_u).
 * Shadow rays use the scene's transmittance estimator over all the lanes and MIS against
 * phase sampling over directions (scatter.cl, shade.cl): the prefix's MIS weight is in beta, and
 * an unbiased, independent estimate of the light at the vertex times it stays unbiased. (pbrt-v4
 * also MIS-weights the shadow ray's null collisions across channels; ratio tracking with the
 * channels' max majorant keeps every channel's factor in [0, 1] when the majorant bounds, so that
 * refinement is not needed here.) No control component: the tracker does not decompose. */

inline int tracker_is_mis(__constant const st_scene* scene) {
  return ST_HAS_SPECTRAL_MIS && scene->tracker == ST_TRACKER_SPECTRAL_MIS;
}

/* beta and r_u scaled by one factor so that mean(r_u) = 1 (the score beta / mean(r_u) is kept). */
inline void mis_rescale(float4* beta, float4* r_u, float4 lanes) {
  float m = masked_avg(*r_u, lanes);
  if (m > 0.0f) {
    *beta /= m;
    *r_u /= m;
  } else {
    *beta = *r_u = (float4)(0.0f);
  }
}

/* The per-channel majorant of the walker's current segment, with the hero's entry the walker's
 * own flight rate (so that the hero's flight ratio is exactly 1). */
inline float4 mis_sigma_maj(__constant const st_scene* scene, const st_walker* w, int hero) {
  float4 sigma_maj = select((float4)(0.0f), (float4)(w->mu_bar), isnotequal(scene_lanes(scene), (float4)(0.0f)));
  if (ST_HAS_CHROMATIC) {
    /* each medium's extinction per unit density: the path's wavelengths' (spectral), a colour
     * grid's bound, else its own */
    float4 sigma_t[ST_KERNEL_MAX_MEDIA];
    for (int i = 0; i < ST_KERNEL_MAX_MEDIA; ++i) {
      sigma_t[i] = (float4)(0.0f);
      if (i >= scene->n_media) continue;
      __constant const st_medium* m = &scene->media[i];
      sigma_t[i] = medium_is_spectral(m) ? w->sigma_t_l[i] : medium_has_color(m) ? m->sigma_t_maj : m->sigma_a + m->sigma_s;
    }
    sigma_maj = majorant_segment_sigma_maj(scene, &w->maj, sigma_t) * scene_lanes(scene);
  }
  return select(sigma_maj, (float4)(w->mu_bar), isnotequal(one_hot(hero), (float4)(0.0f)));
}

/* The body of spectral-MIS free-path sampling at a tentative collision at p; sigma_maj: the
 * segment's majorant per channel. Returns ST_EV_ABSORB, ST_EV_SCATTER (*medium) or ST_EV_NULL. */
inline int mis_collision(__constant const st_scene* scene, __global const uint* grids, const st_walker* w, float3 p,
                         float4 sigma_maj, int hero, float4* beta, float4* r_u, float4* L, int* medium, st_rng* rng,
                         st_track_stats* st) {
  const float4 lanes = scene_lanes(scene); /* every lane of the scene: channels or wavelengths */
  st_medium_point k = medium_sample_point(scene, grids, p, &st->lookups, 0, rng, w->sigma_a_l, w->sigma_s_l);
  st_collision c;
  c.sigma_a = k.sigma_a * lanes;
  c.sigma_s = k.sigma_s * lanes;
  c.sigma_n = sigma_maj - c.sigma_a - c.sigma_s;
  c.mu_bar = channel_of(sigma_maj, hero);
  for (int i = 0; i < ST_KERNEL_MAX_MEDIA; ++i) {
    c.density[i] = k.density[i];
    c.tint[i] = k.tint[i];
  }
  if (ST_HAS_EMISSION) { /* the collision estimator of emission, MIS-weighted over the techniques */
    float4 mua_Le = absorbed_emission(scene, grids, &c, p, rng->time, &st->emission_lookups, rng->lambda);
    float pdf = masked_avg(*r_u * sigma_maj, lanes);
    if (pdf > 0.0f) *L += *beta * lanes * mua_Le / pdf;
  }
  int weighted = absorption_as_weight(scene);
  float4 P_a = weighted ? (float4)(0.0f) : fabs(c.sigma_a);
  float4 P_s = weighted ? fabs(c.sigma_a) + fabs(c.sigma_s) : fabs(c.sigma_s);
  float4 P_n = fabs(c.sigma_n);
  float4 S = P_a + P_s + P_n;
  /* technique k's density of "a collision here, then event e" is P_e,k * rate_k */
  float4 rate = select((float4)(0.0f), sigma_maj / S, isgreater(S, (float4)(0.0f)));
  float S_h = channel_of(S, hero);
  if (!(S_h > 0.0f)) {
    *beta = (float4)(0.0f);
    return ST_EV_ABSORB;
  }
  float xi = rng_uniform(rng) * S_h;
  float Pa_h = channel_of(P_a, hero), Ps_h = channel_of(P_s, hero);
  if (xi < Pa_h) {
    st->real += 1u;
    *beta = (float4)(0.0f);
    return ST_EV_ABSORB;
  }
  if (xi < Pa_h + Ps_h) {
    st->real += 1u;
    float4 sigma_s_k;
    float inv_p;
    int m = choose_scattering_medium(scene, grids, &c, lanes, lanes, rng, &sigma_s_k, &inv_p);
    if (m < 0) {
      *beta = (float4)(0.0f);
      return ST_EV_ABSORB;
    }
    /* f gains sigma_s,k / p(k), every technique's pdf P_s rate (the common 1 / p_h cancels in the rescale) */
    *beta *= sigma_s_k * lanes * inv_p;
    *r_u *= P_s * rate;
    mis_rescale(beta, r_u, lanes);
    if (!(masked_max(fabs(*beta), lanes) > 0.0f)) {
      *beta = (float4)(0.0f);
      return ST_EV_ABSORB;
    }
    *medium = m;
    st->max_beta = fmax(st->max_beta, masked_max(fabs(*beta), lanes));
    return ST_EV_SCATTER;
  }
  *beta *= c.sigma_n;
  *r_u *= P_n * rate;
  mis_rescale(beta, r_u, lanes);
  st->nulls += 1u;
  st->max_beta = fmax(st->max_beta, masked_max(fabs(*beta), lanes));
  return ST_EV_NULL;
}

/* Spectral-MIS free-path sampling along (o, d) from *t (the contract of track_free_path); beta and
 * r_u as above, hero the path's hero channel. */
inline int track_free_path_mis(__constant const st_scene* scene, __global const uint* grids, __global const float2* maj,
                               float3 o, float3 d, float* t, float t_max, float4* beta, float4* r_u, int hero,
                               float4* L, int* medium, st_rng* rng, int budget, st_track_stats* st) {
  st_walker w;
  walker_begin(scene, maj, &w, o, d, *t, t_max, one_hot(hero), rng->lambda, 0, ST_WALK_SAMPLE_CONTROL, budget);
  float4 sigma_maj = mis_sigma_maj(scene, &w, hero);
  for (;;) {
    float t_prev = w.t, t_end = w.seg.t1;
    int step = walker_step(scene, maj, &w, rng, &st->dda_steps, &st->dda_nonempty);
    *t = w.t;
    if (step == ST_WALK_DONE) return ST_EV_ESCAPE;
    if (step == ST_WALK_BUDGET) return ST_EV_BUDGET;
    /* the flight: f_c gains T_maj,c and p_k gains T_maj,k; relative to the hero's, exp(-(sigma_maj - sigma_maj,h) dt) */
    if (ST_HAS_CHROMATIC) {
      float dt = (step == ST_WALK_COLLISION ? w.t : t_end) - t_prev;
      const float4 lanes = scene_lanes(scene);
      float4 ratio = exp(-(sigma_maj - (float4)(channel_of(sigma_maj, hero))) * fmax(dt, 0.0f)) * lanes;
      *beta *= ratio;
      *r_u *= ratio;
      mis_rescale(beta, r_u, lanes);
    }
    if (step == ST_WALK_CROSSED) {
      sigma_maj = mis_sigma_maj(scene, &w, hero);
      continue;
    }
    int ev = mis_collision(scene, grids, &w, o + w.t * d, sigma_maj, hero, beta, r_u, L, medium, rng, st);
    if (ev != ST_EV_NULL) return ev;
  }
}

/* The scene's tracker: spectral MIS (r_u and hero its state) or track_free_path (mask), up to t_max. */
inline int track_path(__constant const st_scene* scene, __global const uint* grids, __global const float2* maj,
                      float3 o, float3 d, float* t, float t_max, float4* beta, float4* r_u, int hero, float4 mask,
                      float4* L, int* medium, st_rng* rng, int budget, st_track_stats* st) {
  if (tracker_is_mis(scene))
    return track_free_path_mis(scene, grids, maj, o, d, t, t_max, beta, r_u, hero, L, medium, rng, budget, st);
  return track_free_path(scene, grids, maj, o, d, t, t_max, beta, mask, L, medium, rng, budget, st);
}

/* A path's hero lane (spectral-mis), uniform over the scene's lanes; 0 for the other trackers (no draw). */
inline int draw_hero(__constant const st_scene* scene, st_rng* rng) {
  const uint n = (uint)scene_n_lanes(scene);
  return tracker_is_mis(scene) ? (int)min((uint)(rng_uniform(rng) * (float)n), n - 1u) : 0;
}

#endif
