/* tracking.h: free-path sampling and transmittance, on the integral formulation of
 * null-collision algorithms (ALGORITHMS.md 2.2).
 *
 * One routine serves every tracker. Per majorant segment a gray free-path coefficient mubar is
 * used; at each tentative collision the event (absorption, scattering, null) is chosen with
 * probabilities P* = v* / C from the tracker's scheme, and the path weight beta is multiplied by
 * mu* / (mubar P*). The trackers are choices of mubar's channel set (the path's mask) and the
 * scheme:
 *   delta-per-channel: mask = one channel, beta = e_c      -> analog delta tracking of channel c
 *   delta:             mask = rgb, achromatic media, max    -> analog delta tracking
 *   spectral:          mask = rgb, the chosen scheme (max, average, history-max, history-average)
 * The |.| in the probabilities keeps every tracker unbiased when a majorant does not bound
 * (negative null coefficient: weighted tracking, ALGORITHMS.md 2.5); with a bounding majorant
 * the delta trackers' weights are exactly analog.
 * Emission is scored at absorption events only: beta * mu_a Le / (mubar P_a) (ALGORITHMS.md 2.4).
 * Every loop has an iteration budget; when it is spent the routine returns ST_EV_BUDGET with t at
 * a point where no collision is pending, and the caller re-queues the item (never a cap that
 * biases).
 */
#ifndef SPECTRACK_TRACKING_H
#define SPECTRACK_TRACKING_H

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
  return (scene->tracker == ST_TRACKER_SPECTRAL || scene->tracker == ST_TRACKER_SPECTRAL_DECOMPOSITION)
             ? scene->scheme : ST_SCHEME_MAX;
}

inline int tracker_decomposes(__constant const st_scene* scene) {
  return ST_HAS_DECOMPOSITION && (scene->tracker == ST_TRACKER_DECOMPOSITION || scene->tracker == ST_TRACKER_SPECTRAL_DECOMPOSITION);
}

inline float scheme_reduce(int scheme, float4 v, float4 mask) {
  return (scheme == ST_SCHEME_MAX || scheme == ST_SCHEME_HISTORY_MAX) ? masked_max(v, mask) : masked_avg(v, mask);
}

/* Un-normalised probabilities (absorption, scattering, null) of the scheme. */
inline float3 event_values(int scheme, float4 beta, float4 mask, float4 sa, float4 ss, float4 sn) {
  int history = scheme == ST_SCHEME_HISTORY_MAX || scheme == ST_SCHEME_HISTORY_AVERAGE;
  float4 w = history ? fabs(beta) * mask : mask;
  return (float3)(scheme_reduce(scheme, w * fabs(sa), mask), scheme_reduce(scheme, w * fabs(ss), mask),
                  scheme_reduce(scheme, w * fabs(sn), mask));
}

/* The free-path-sampling components of one majorant segment (ALGORITHMS.md 3, 5).
 * Control: the homogeneous part dmin * minorant_scale of every medium, with per-channel
 * coefficients ca, cs and a gray coefficient bar_c = max over the path's channels of ca + cs
 * (control collisions can be null for thin channels; no lookup is needed to classify them).
 * Residual: everything else, tracked with the gray coefficient bar_r, which bounds |residual|
 * when the grid's bounds hold; otherwise the |.| probabilities keep it exact. Without
 * decomposition the control is empty and bar_r is the ordinary majorant. */
typedef struct {
  float bar_c, bar_r;
  float4 ca, cs;
  float cd[ST_KERNEL_MAX_MEDIA]; /* control density of each medium */
} st_components;

inline st_components segment_components(__constant const st_scene* scene, const st_segments* seg, float4 mask,
                                        int decompose) {
  st_components c;
  c.bar_r = 0.0f;
  c.ca = c.cs = (float4)(0.0f);
  for (int i = 0; i < ST_KERNEL_MAX_MEDIA; ++i) {
    c.cd[i] = 0.0f;
    if (i >= scene->n_media || seg->m[i].state != ST_DDA_INSIDE) continue;
    __constant const st_medium* m = &scene->media[i];
    float gray = medium_gray_sigma_t(m, mask);
    float dmax = seg->m[i].dmax, dmin = seg->m[i].dmin;
    float dmax_s = dmax * m->majorant_scale;
    if (decompose) {
      float dc = dmin * m->minorant_scale;
      c.cd[i] = dc;
      c.ca += dc * m->sigma_a;
      c.cs += dc * m->sigma_s;
      /* > 0 whenever the residual can be non-zero, even with scaled (non-bounding) bounds */
      float r = fmax(fmax(dmax_s - dc, m->majorant_scale * (dmax - dmin)), dc - dmin);
      c.bar_r += fmax(r, 0.0f) * gray;
    } else {
      c.bar_r += dmax_s * gray;
    }
  }
  c.bar_c = decompose ? fmax(masked_max(c.ca + c.cs, mask), 0.0f) : 0.0f;
  return c;
}

/* Samples the next real collision along (o, d) from *t. On ST_EV_SCATTER, *t is the collision,
 * beta carries the scattering weight and *medium the medium whose phase function applies. On
 * ST_EV_ABSORB the emission score has been added to *L. On ST_EV_ESCAPE the ray left every
 * medium. On ST_EV_BUDGET, call again from *t. Each tentative collision belongs to the control
 * component with probability bar_c / (bar_c + bar_r) (the race of two exponential flights) and
 * is classified with that component's own coefficients (option A of ALGORITHMS.md 3.3). */
inline int track_free_path(__constant const st_scene* scene, __global const uint* grids, __global const float2* maj,
                           float3 o, float3 d, float* t, float4* beta, float4 mask, float4* L, int* medium,
                           st_rng* rng, int budget, st_track_stats* st) {
  st_segments seg;
  segments_init(scene, maj, &seg, o, d, *t);
  int scheme = tracker_scheme(scene);
  int decompose = tracker_decomposes(scene);
  st_components comp = segment_components(scene, &seg, mask, decompose);
  for (int iter = 0;; ++iter) {
    if (segments_done(&seg)) {
      *t = seg.t;
      return ST_EV_ESCAPE;
    }
    if (iter >= budget) {
      *t = seg.t;
      return ST_EV_BUDGET;
    }
    float bar = comp.bar_c + comp.bar_r;
    float tc = bar > 0.0f ? seg.t + sample_exponential(rng_uniform(rng), bar) : INFINITY;
    if (!(tc < seg.end)) {
      st->dda_steps += segments_next(scene, maj, &seg, &st->dda_nonempty);
      comp = segment_components(scene, &seg, mask, decompose);
      continue;
    }
    seg.t = tc;
    float3 p = o + tc * d;
    float4 sa, ss;
    float mb;
    float dens[ST_KERNEL_MAX_MEDIA]; /* each medium's part of this component's density */
    if (comp.bar_c > 0.0f && rng_uniform(rng) * bar < comp.bar_c) {
      sa = comp.ca;  /* control collision: constants, no density lookup */
      ss = comp.cs;
      mb = comp.bar_c;
      for (int i = 0; i < ST_KERNEL_MAX_MEDIA; ++i) dens[i] = comp.cd[i];
      st->control += 1u;
    } else {
      st_coeffs c = scene_coeffs(scene, grids, p, &st->lookups);
      sa = c.sigma_a - comp.ca;
      ss = c.sigma_s - comp.cs;
      mb = comp.bar_r;
      for (int i = 0; i < ST_KERNEL_MAX_MEDIA; ++i) dens[i] = c.density[i] - comp.cd[i];
      if (decompose) st->residual += 1u;
    }
    float4 sn = mb - sa - ss;
    float3 v = event_values(scheme, *beta, mask, sa, ss, sn);
    float C = v.x + v.y + v.z;
    if (!(C > 0.0f)) { /* nothing left to carry on any channel */
      *t = tc;
      *beta = (float4)(0.0f);
      return ST_EV_ABSORB;
    }
    float u = rng_uniform(rng) * C;
    if (u < v.x) {
      if (ST_HAS_EMISSION) {
        float4 muaLe = (float4)(0.0f);
        for (int i = 0; i < ST_KERNEL_MAX_MEDIA; ++i) {
          if (i >= scene->n_media || dens[i] == 0.0f) continue;
          __constant const st_medium* m = &scene->media[i];
          if (m->emissive) muaLe += dens[i] * m->sigma_a * medium_Le(m, grids, p, &st->emission_lookups);
        }
        *L += *beta * mask * muaLe * (C / (mb * v.x));
      }
      st->real += 1u;
      *t = tc;
      return ST_EV_ABSORB;
    }
    if (u < v.x + v.y) {
      /* choose the medium whose phase function scatters, in proportion to |beta * sigma_s| */
      int k = 0;
      float4 ss_k = ss;
      float qtot = 1.0f, qk = 1.0f;
      if (ST_HAS_MULTI_MEDIUM && scene->n_media > 1) {
        float q[ST_KERNEL_MAX_MEDIA];
        float total = 0.0f;
        for (int i = 0; i < ST_KERNEL_MAX_MEDIA; ++i) {
          q[i] = 0.0f;
          if (i >= scene->n_media) continue;
          q[i] = masked_avg(fabs(*beta * dens[i] * scene->media[i].sigma_s), mask);
          total += q[i];
        }
        float uq = rng_uniform(rng) * total;
        k = -1;
        for (int i = 0; i < ST_KERNEL_MAX_MEDIA; ++i) {
          if (i >= scene->n_media || q[i] <= 0.0f) continue;
          k = i;
          if (uq < q[i]) break;
          uq -= q[i];
        }
        if (k < 0) { /* no medium scatters any carried channel */
          *t = tc;
          *beta = (float4)(0.0f);
          return ST_EV_ABSORB;
        }
        ss_k = dens[k] * scene->media[k].sigma_s;
        qk = q[k];
        qtot = total;
      }
      *beta *= ss_k * (qtot / qk) * (C / (mb * v.y));
      *medium = k;
      st->real += 1u;
      st->max_beta = fmax(st->max_beta, masked_max(fabs(*beta), mask));
      *t = tc;
      return ST_EV_SCATTER;
    }
    *beta *= sn * (C / (mb * v.z));
    st->nulls += 1u;
    st->max_beta = fmax(st->max_beta, masked_max(fabs(*beta), mask));
  }
}

/* Transmittance along (o, d) from *t to the end of every medium, per channel: ratio tracking,
 * or residual ratio tracking for the decomposition trackers (the control part exp(-mu_c dt) in
 * closed form, ratio tracking of the residual with bar_r). Russian roulette on small estimates
 * (unbiased; pbrt's constants). Returns 1 when finished, 0 when the budget is spent (call again
 * from *t). */
inline int ratio_track(__constant const st_scene* scene, __global const uint* grids, __global const float2* maj,
                       float3 o, float3 d, float* t, float4* T, float4 mask, st_rng* rng, int budget,
                       st_track_stats* st) {
  st_segments seg;
  segments_init(scene, maj, &seg, o, d, *t);
  int decompose = tracker_decomposes(scene);
  st_components comp = segment_components(scene, &seg, mask, decompose);
  for (int iter = 0;; ++iter) {
    if (segments_done(&seg)) {
      *t = seg.t;
      return 1;
    }
    if (iter >= budget) {
      *t = seg.t;
      return 0;
    }
    float tc = comp.bar_r > 0.0f ? seg.t + sample_exponential(rng_uniform(rng), comp.bar_r) : INFINITY;
    float t_to = fmin(tc, seg.end);
    if (decompose) *T *= exp(-(comp.ca + comp.cs) * (t_to - seg.t)) * mask;
    int segment_end = !(tc < seg.end);
    if (segment_end) {
      st->dda_steps += segments_next(scene, maj, &seg, &st->dda_nonempty);
      comp = segment_components(scene, &seg, mask, decompose);
    } else {
      seg.t = tc;
      st_coeffs c = scene_coeffs(scene, grids, o + tc * d, &st->lookups);
      float4 residual = c.sigma_a + c.sigma_s - comp.ca - comp.cs;
      *T *= mask * ((comp.bar_r - residual) / comp.bar_r);
    }
    /* Russian roulette after every update of the estimate (also after the closed-form control
     * factor, which can make T tiny without any lookup) */
    float m = masked_max(fabs(*T), mask);
    if (m < 0.05f) {
      if (m == 0.0f || rng_uniform(rng) < 0.75f) {
        *T = (float4)(0.0f);
        *t = seg.t;
        return 1;
      }
      *T /= 0.25f;
    }
  }
}

#endif
