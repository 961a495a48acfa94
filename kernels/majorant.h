/* majorant.h: majorant segments along a ray, through every medium at once; walker.h steps the
 * exponential flights of every tracker through them.
 *
 * Each medium has a sparse grid of (dmax, dmin) cells in its index space, walked by a 3D DDA
 * (after pbrt-v4's DDAMajorantIterator; docs/estimators.md, 'Walking the grid'). The merged DDA (st_segments) ends
 * its current segment at the first cell boundary or medium boundary of any medium; the plain
 * segment the trackers see (st_segment) holds [t0, t1) and its free-path components: the
 * control coefficients and the residual bound (segments_current). Cells with dmax = 0 give
 * segments with zero majorant, which tracking crosses with no lookup.
 *
 * The adaptive hierarchy (maj_block = B > 1, docs/majorant-hierarchy.md): the fine grid is cut
 * into blocks of B^3 cells and each block has its own level, chosen at load by a cost model: it
 * is walked in groups of r^3 fine cells (r = 1, 2, 4, .. B, dividing B), each group with the max
 * dmax and min dmin of its cells; r = B walks the block in one step (empty blocks always). Fine
 * groups where the density changes keep the bounds (above all the minorant) tight; coarse groups
 * where it is empty or nearly uniform save DDA steps and free flights. The DDA steps by r; on
 * entering a block of another level it recomputes the group holding the ray and its face
 * crossings from the ray (not accumulated). Zero-majorant segments draw no random numbers.
 *
 * The walker (walker.h: st_walker, walker_step) owns the merged DDA, the exponential flights and
 * the iteration budget; tracking.h keeps only the bodies run at each tentative collision.
 *
 * The DDA holds no state between launches: a path that stops (budget, scatter) restarts it at
 * its current t. That is exact because free flights restart at any point where no collision is
 * pending (memoryless property, docs/estimators.md, 'Walking the grid'). Compiled without fast/finite math, so
 * 1/0 = inf for axis-parallel rays; -0.0 components are made +0.0.
 */
#ifndef SPECTRACK_MAJORANT_H
#define SPECTRACK_MAJORANT_H

#include "types.h"
#include "features.h"
#include "rng.h"
#include "sampling.h"
#include "spectrum.h"
#include "medium.h"

#define ST_DDA_BEFORE 0
#define ST_DDA_INSIDE 1
#define ST_DDA_DONE 2

typedef struct {
  float3 o, d;       /* ray in index space (same t as in world space) */
  float3 t_next, dt; /* next crossing per axis, crossing spacing of the current group */
  int3 cell, step;   /* cell: the current group's first fine cell */
  int r;             /* group edge in fine cells: 1 (one-level grids, the finest level) .. maj_block */
  uint pool_base;    /* hierarchy: the current refined block's first group in maj */
  float t_enter, t_exit;
  float seg_end;     /* where this medium's current segment ends */
  float dmax, dmin;  /* current group (0 outside) */
  int state;
} st_dda;

inline float2 majorant_cell(__constant const st_medium* m, __global const float2* maj, int3 c) {
  return maj[m->maj_offset + (uint)(c.x + m->maj_dims[0] * (c.y + m->maj_dims[1] * c.z))];
}

/* Index 0, 1, 2 of the smallest component (ties to the lower axis, as the DDA steps). */
inline int dda_min_axis(float3 t) {
  return (t.x <= t.y) ? ((t.x <= t.z) ? 0 : 2) : ((t.y <= t.z) ? 1 : 2);
}

/* ---- the adaptive hierarchy (maj_block = B > 1; docs/majorant-hierarchy.md) ----
 * Blocks of B^3 fine cells. Each block's entry (at maj_coarse_offset, x fastest) is either
 * (dmax, dmin) >= 0: the block is walked whole, as one group of B^3 cells; or (-r, pool offset):
 * the block is walked in groups of r^3 fine cells (r divides B), whose (B/r)^3 bounds lie at
 * maj_offset + pool offset (the offset's bits stored in the float), x fastest. */
inline float2 majorant_block_entry(__constant const st_medium* m, __global const float2* maj, int3 c) {
  int B = m->maj_block;
  int3 dims = (int3)(m->maj_dims[0], m->maj_dims[1], m->maj_dims[2]);
  int3 cdims = (dims + B - 1) / B;
  int3 blk = c / B;
  return maj[m->maj_coarse_offset + (uint)(blk.x + cdims.x * (blk.y + cdims.y * blk.z))];
}

inline int majorant_entry_group(__constant const st_medium* m, float2 e) {
  return e.x >= 0.0f ? m->maj_block : (int)(-e.x);
}

/* Bounds of the group of edge r holding fine cell c, in a refined block whose groups start at base. */
inline float2 majorant_group(__constant const st_medium* m, __global const float2* maj, uint base, int r, int3 c) {
  int B = m->maj_block, n = B / r;
  int3 l = (c - (c / B) * B) / r;
  return maj[base + (uint)(l.x + n * (l.y + n * l.z))];
}

/* The bounds the walk uses at fine cell c: its group's. */
inline float2 majorant_bounds_at(__constant const st_medium* m, __global const float2* maj, int3 c) {
  if (ST_HAS_COARSE_MAJORANT && m->maj_block > 1) {
    float2 e = majorant_block_entry(m, maj, c);
    if (e.x >= 0.0f) return e;
    return majorant_group(m, maj, m->maj_offset + as_uint(e.y), majorant_entry_group(m, e), c);
  }
  return majorant_cell(m, maj, c);
}

/* The DDA entered a block of another level (group edge s->r) at parameter t, across a face of
 * axis `axis` (-1: s->cell is the fine cell holding the ray at t, the start of a walk). The group
 * is the one holding the ray at t: the fine cell is recomputed from the ray and clamped into the
 * block (the crossed axis: the cell next to the face), and so are the crossings (not
 * accumulated), never before t. */
inline void dda_set_group(__constant const st_medium* m, st_dda* s, float t, int axis) {
  int B = m->maj_block, r = s->r;
  float cs = m->maj_origin.w;
  float3 org = m->maj_origin.xyz;
  int3 lo_c = (s->cell / B) * B;
  if (axis >= 0) {
    int3 dims = (int3)(m->maj_dims[0], m->maj_dims[1], m->maj_dims[2]);
    int3 hi_c = min(lo_c + B, dims) - 1;
    int3 fc = clamp(convert_int3_rtn((s->o + t * s->d - org) / cs), lo_c, hi_c);
    int3 face = select(hi_c, lo_c, s->step > 0);
    if (axis == 0) fc.x = face.x; else if (axis == 1) fc.y = face.y; else fc.z = face.z;
    s->cell = fc;
  }
  s->cell = lo_c + ((s->cell - lo_c) / r) * r;
  float gs = cs * (float)r;
  float3 lo = org + convert_float3(s->cell) * cs;
  float3 bound = select(lo, lo + gs, s->d > 0.0f);
  float3 tn = fmax((bound - s->o) / s->d, (float3)(t));
  s->t_next = select(tn, (float3)(INFINITY), s->d == 0.0f);
  s->dt = select(gs / fabs(s->d), (float3)(INFINITY), s->d == 0.0f);
}

/* Loads (dmax, dmin) of the DDA's group, entered at t across a face of `axis` (-1: the walk
 * starts there). new_block: the group may lie in another
 * block than the previous one (only then is the block's entry read: its level, and a refined
 * block's pool base, stay in s->r and s->pool_base). */
inline void dda_load_cell(__constant const st_medium* m, __global const float2* maj, st_dda* s, int new_block,
                          float t, int axis) {
  if (ST_HAS_COARSE_MAJORANT && m->maj_block > 1) {
    if (new_block) {
      float2 e = majorant_block_entry(m, maj, s->cell);
      int r = majorant_entry_group(m, e);
      if (r != s->r) {
        s->r = r;
        dda_set_group(m, s, t, axis);
      }
      if (e.x >= 0.0f) {
        s->dmax = e.x;
        s->dmin = e.y;
        return;
      }
      s->pool_base = m->maj_offset + as_uint(e.y);
    }
    float2 v = majorant_group(m, maj, s->pool_base, s->r, s->cell);
    s->dmax = v.x;
    s->dmin = v.y;
    return;
  }
  float2 v = majorant_cell(m, maj, s->cell);
  s->dmax = v.x;
  s->dmin = v.y;
}

inline void dda_enter_cell(__constant const st_medium* m, __global const float2* maj, st_dda* s, float t) {
  float cs = m->maj_origin.w;
  int3 dims = (int3)(m->maj_dims[0], m->maj_dims[1], m->maj_dims[2]);
  float3 p = s->o + t * s->d;
  float3 rel = (p - m->maj_origin.xyz) / cs;
  s->cell = clamp(convert_int3_rtn(rel), (int3)(0), dims - 1);
  float3 lo = m->maj_origin.xyz + convert_float3(s->cell) * cs;
  float3 bound = select(lo, lo + cs, s->d > 0.0f);
  float3 tn = t + (bound - p) / s->d;
  s->t_next = select(tn, (float3)(INFINITY), s->d == 0.0f);
  s->dt = select(cs / fabs(s->d), (float3)(INFINITY), s->d == 0.0f);
  s->step = select((int3)(-1), (int3)(1), s->d > 0.0f);
  s->r = 1;
  s->state = ST_DDA_INSIDE;
  dda_load_cell(m, maj, s, 1, t, -1);
  s->seg_end = fmin(fmin(fmin(s->t_next.x, s->t_next.y), s->t_next.z), s->t_exit);
}

/* Starts the DDA of medium m for the world ray (o, d) at parameter t. */
inline void dda_init(__constant const st_medium* m, __global const float2* maj, st_dda* s, float3 o, float3 d, float t) {
  s->o = medium_to_index(m, o);
  s->d = medium_dir_to_index(m, d);
  s->d = select(s->d, (float3)(0.0f), s->d == 0.0f); /* -0.0 -> +0.0 */
  medium_box_interval(m, s->o, s->d, &s->t_enter, &s->t_exit);
  s->dmax = 0.0f;
  s->dmin = 0.0f;
  s->pool_base = 0u;
  s->r = 1;
  if (!(s->t_exit > fmax(t, s->t_enter))) {
    s->state = ST_DDA_DONE;
    s->seg_end = INFINITY;
  } else if (t < s->t_enter) {
    s->state = ST_DDA_BEFORE;
    s->seg_end = s->t_enter;
  } else {
    dda_enter_cell(m, maj, s, t);
  }
}

/* Moves medium m's DDA past its current segment end. */
inline void dda_advance(__constant const st_medium* m, __global const float2* maj, st_dda* s) {
  if (s->state == ST_DDA_BEFORE) {
    dda_enter_cell(m, maj, s, s->t_enter);
    return;
  }
  if (s->seg_end >= s->t_exit) {
    s->state = ST_DDA_DONE;
    s->seg_end = INFINITY;
    s->dmax = s->dmin = 0.0f;
    return;
  }
  int axis = dda_min_axis(s->t_next);
  int3 dims = (int3)(m->maj_dims[0], m->maj_dims[1], m->maj_dims[2]);
  int r = s->r, c_axis, step_axis;
  float t_cross;
  if (axis == 0) { t_cross = s->t_next.x; s->cell.x += s->step.x * r; s->t_next.x += s->dt.x; c_axis = s->cell.x; step_axis = s->step.x; }
  else if (axis == 1) { t_cross = s->t_next.y; s->cell.y += s->step.y * r; s->t_next.y += s->dt.y; c_axis = s->cell.y; step_axis = s->step.y; }
  else { t_cross = s->t_next.z; s->cell.z += s->step.z * r; s->t_next.z += s->dt.z; c_axis = s->cell.z; step_axis = s->step.z; }
  if (any(s->cell < 0) || any(s->cell >= dims)) {
    s->state = ST_DDA_DONE;
    s->seg_end = INFINITY;
    s->dmax = s->dmin = 0.0f;
    return;
  }
  /* a step enters another block only across a block face: the group [c, c + r) was entered at
   * plane c (stepping up) or c + r (stepping down) */
  int B = max(m->maj_block, 1);
  dda_load_cell(m, maj, s, (step_axis > 0) ? (c_axis % B == 0) : ((c_axis + r) % B == 0), t_cross, axis);
  s->seg_end = fmax(s->seg_end, fmin(fmin(fmin(s->t_next.x, s->t_next.y), s->t_next.z), s->t_exit));
}

/* The merged DDA over all media: the current segment ends at `end`, the first segment end of
 * any medium (INFINITY: no medium ahead). Only the walker below uses it. */
typedef struct {
  st_dda m[ST_KERNEL_MAX_MEDIA];
  float end;
} st_segments;

inline void segments_update_end(__constant const st_scene* scene, st_segments* s) {
  float e = INFINITY;
  for (int i = 0; i < ST_KERNEL_MAX_MEDIA; ++i)
    if (i < scene->n_media) e = fmin(e, s->m[i].seg_end);
  s->end = e;
}

inline void segments_init(__constant const st_scene* scene, __global const float2* maj, st_segments* s, float3 o, float3 d, float t) {
  for (int i = 0; i < ST_KERNEL_MAX_MEDIA; ++i)
    if (i < scene->n_media) dda_init(&scene->media[i], maj, &s->m[i], o, d, t);
  segments_update_end(scene, s);
}

/* Moves to the next segment; returns the number of DDA steps taken and adds to *nonempty those
 * that entered a cell with a non-zero majorant. */
inline uint segments_next(__constant const st_scene* scene, __global const float2* maj, st_segments* s,
                          uint* nonempty) {
  uint steps = 0;
  float e = s->end;
  for (int i = 0; i < ST_KERNEL_MAX_MEDIA; ++i) {
    if (i >= scene->n_media) continue;
    /* a medium may have several zero-length segments at e (corner crossings) */
    for (int k = 0; k < 4 && s->m[i].seg_end <= e; ++k) {
      dda_advance(&scene->media[i], maj, &s->m[i]);
      ++steps;
      if (s->m[i].dmax != 0.0f) *nonempty += 1u;
    }
  }
  segments_update_end(scene, s);
  return steps;
}

/* Gray majorant (and minorant) coefficient of medium i over the channels in mask. */
inline float medium_gray_sigma_t(__constant const st_medium* m, float4 mask) {
  /* a colour grid's extinction bound (medium.h); a colour medium is always chromatic */
  if (medium_has_color(m)) return masked_max(m->sigma_t_maj, mask);
  /* achromatic media: every channel holds the same sum, which is the max over any mask */
  return ST_HAS_CHROMATIC ? masked_max(m->sigma_a + m->sigma_s, mask) : m->sigma_a.x + m->sigma_s.x;
}

/* The majorant of the current segment of the merged DDA per channel (spectral-mis, tracking.h):
 * the sum over the media inside of dmax * majorant_scale * the medium's sigma_t per channel (a
 * colour medium: its extinction bound sigma_t_maj), which segments_current reduces to the gray
 * mu_bar of a path's channels. */
inline float4 segments_sigma_maj(__constant const st_scene* scene, const st_segments* s, const float4* sigma_t_l) {
  float4 sigma_maj = (float4)(0.0f);
  for (int i = 0; i < ST_KERNEL_MAX_MEDIA; ++i) {
    if (i >= scene->n_media || s->m[i].state != ST_DDA_INSIDE) continue;
    __constant const st_medium* m = &scene->media[i];
    float4 sigma_t = medium_is_spectral(m) ? sigma_t_l[i] : medium_has_color(m) ? m->sigma_t_maj : m->sigma_a + m->sigma_s;
    sigma_maj += s->m[i].dmax * m->majorant_scale * sigma_t;
  }
  return sigma_maj * scene_lanes(scene);
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

/* The current segment of the merged DDA, entered at t0, for a path carrying the channels in mask;
 * sigma_a_l, sigma_s_l: spectral media's coefficients at the path's wavelengths (st_walker), which
 * also make their majorant: the extinction's largest value over the wavelengths the path carries. */
inline st_segment segments_current(__constant const st_scene* scene, const st_segments* s, float t0, float4 mask,
                                   const float4* sigma_a_l, const float4* sigma_s_l, int decompose) {
  st_segment g;
  g.t0 = t0;
  g.t1 = s->end;
  g.mu_bar_r = 0.0f;
  g.sigma_a_c = g.sigma_s_c = (float4)(0.0f);
  for (int i = 0; i < ST_KERNEL_MAX_MEDIA; ++i) {
    g.density_c[i] = 0.0f;
    if (i >= scene->n_media || s->m[i].state != ST_DDA_INSIDE) continue;
    __constant const st_medium* m = &scene->media[i];
    float gray = medium_is_spectral(m) ? fmax(masked_max(sigma_a_l[i] + sigma_s_l[i], mask), 0.0f)
                                       : medium_gray_sigma_t(m, mask);
    float dmax = s->m[i].dmax, dmin = s->m[i].dmin;
    float dmax_s = dmax * m->majorant_scale;
    if (decompose && !medium_has_color(m)) { /* a colour medium has no control (medium.h) */
      float dc = dmin * m->minorant_scale;
      g.density_c[i] = dc;
      g.sigma_a_c += dc * (medium_is_spectral(m) ? sigma_a_l[i] : m->sigma_a);
      g.sigma_s_c += dc * (medium_is_spectral(m) ? sigma_s_l[i] : m->sigma_s);
      /* > 0 whenever the residual can be non-zero, even with scaled (non-bounding) bounds */
      float r = fmax(fmax(dmax_s - dc, m->majorant_scale * (dmax - dmin)), dc - dmin);
      g.mu_bar_r += fmax(r, 0.0f) * gray;
    } else {
      g.mu_bar_r += dmax_s * gray;
    }
  }
  g.mu_bar_c = decompose ? fmax(masked_max(g.sigma_a_c + g.sigma_s_c, mask), 0.0f) : 0.0f;
  return g;
}

#endif
