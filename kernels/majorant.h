/* majorant.h: majorant segments along a ray, through every medium at once: the interval
 * iterator of the medium interface (st_majorant_iterator, below), which walker.h steps the
 * exponential flights of every tracker through.
 *
 * Each medium has a sparse grid of (dmax, dmin) cells in its index space, walked by a 3D DDA
 * (after pbrt-v4's DDAMajorantIterator; docs/estimators.md, 'Walking the grid'). The iterator
 * merges the media's DDAs: it ends its current segment at the first cell boundary or medium
 * boundary of any medium and yields [t0, t1) with each medium's (dmax, dmin) over it. Cells with
 * dmax = 0 give segments with zero majorant, which tracking crosses with no lookup.
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
 * The walker (walker.h: st_walker, walker_step) owns the iterator, the exponential flights and
 * the iteration budget, and makes the trackers' components of each segment (tracker_segment);
 * tracking.h keeps only the bodies run at each tentative collision.
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
 * Blocks of B^3 fine cells, each with a typed entry (types.h st_maj_block) at maj_coarse_offset,
 * x fastest: its group edge r and, for a refined block (r < B), where its (B/r)^3 group bounds
 * lie in the pool at maj_offset. majorant_block_entry is the one place that reads entries. */
inline st_maj_block majorant_block_entry(__constant const st_medium* m, __global const float2* maj, int3 c) {
  int B = m->maj_block;
  int3 dims = (int3)(m->maj_dims[0], m->maj_dims[1], m->maj_dims[2]);
  int3 cdims = (dims + B - 1) / B;
  int3 blk = c / B;
  __global const st_maj_block* entries = (__global const st_maj_block*)(maj + m->maj_coarse_offset);
  return entries[(uint)(blk.x + cdims.x * (blk.y + cdims.y * blk.z))];
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
    st_maj_block e = majorant_block_entry(m, maj, c);
    if (e.group == m->maj_block) return (float2)(e.dmax, e.dmin);
    return majorant_group(m, maj, m->maj_offset + e.pool, e.group, c);
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
      st_maj_block e = majorant_block_entry(m, maj, s->cell);
      if (e.group != s->r) {
        s->r = e.group;
        dda_set_group(m, s, t, axis);
      }
      if (e.group == m->maj_block) {
        s->dmax = e.dmax;
        s->dmin = e.dmin;
        return;
      }
      s->pool_base = m->maj_offset + e.pool;
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

/* ---- the interval iterator: majorant segments through every medium at once ----
 * (after OpenVKL's interval iterators and pbrt-v4's RayMajorantIterator). majorant_iterator_init
 * starts it on a ray at parameter t and yields the segment holding t; each
 * majorant_iterator_next yields the next segment [t0, t1), each with every medium's density
 * bounds over it, which hold the hierarchy's levels and entries out of sight. A segment ends at the first cell, group,
 * block or box boundary of any medium; t1 = INFINITY: no medium ahead (the walk is over). What
 * a tracker makes of the bounds (its channels, a control and a residual) is its own
 * (walker.h); majorant_segment_sigma_maj gives the plain per-channel majorant. */
typedef struct {
  float t0, t1;
  float dmax[ST_KERNEL_MAX_MEDIA]; /* each medium's density majorant over [t0, t1) (0 outside it) */
  float dmin[ST_KERNEL_MAX_MEDIA]; /* and its minorant (0 outside it) */
} st_majorant_segment;

typedef struct {
  st_dda m[ST_KERNEL_MAX_MEDIA];
  float t0, end; /* the current segment: [t0, end) */
} st_majorant_iterator;

/* The iterator's current segment into *seg. */
inline void majorant_iterator_segment(__constant const st_scene* scene, st_majorant_iterator* it,
                                      st_majorant_segment* seg) {
  float e = INFINITY;
  for (int i = 0; i < ST_KERNEL_MAX_MEDIA; ++i)
    if (i < scene->n_media) e = fmin(e, it->m[i].seg_end);
  it->end = e;
  seg->t0 = it->t0;
  seg->t1 = e;
  for (int i = 0; i < ST_KERNEL_MAX_MEDIA; ++i) {
    const int inside = i < scene->n_media && it->m[i].state == ST_DDA_INSIDE;
    seg->dmax[i] = inside ? it->m[i].dmax : 0.0f;
    seg->dmin[i] = inside ? it->m[i].dmin : 0.0f;
  }
}

/* Starts the iterator on the world ray (o, d) at parameter t; *seg: the first segment (the one
 * holding t). */
inline void majorant_iterator_init(__constant const st_scene* scene, __global const float2* maj,
                                   st_majorant_iterator* it, float3 o, float3 d, float t, st_majorant_segment* seg) {
  for (int i = 0; i < ST_KERNEL_MAX_MEDIA; ++i)
    if (i < scene->n_media) dda_init(&scene->media[i], maj, &it->m[i], o, d, t);
  it->t0 = t;
  majorant_iterator_segment(scene, it, seg);
}

/* Moves every medium's DDA past the current segment's end and yields the next segment into *seg;
 * the DDA steps are added to *steps, those that entered a cell with a non-zero majorant also to
 * *nonempty. */
inline void majorant_iterator_next(__constant const st_scene* scene, __global const float2* maj,
                                   st_majorant_iterator* it, st_majorant_segment* seg, uint* steps, uint* nonempty) {
  float e = it->end;
  for (int i = 0; i < ST_KERNEL_MAX_MEDIA; ++i) {
    if (i >= scene->n_media) continue;
    /* a medium may have several zero-length segments at e (corner crossings) */
    for (int k = 0; k < 4 && it->m[i].seg_end <= e; ++k) {
      dda_advance(&scene->media[i], maj, &it->m[i]);
      *steps += 1u;
      if (it->m[i].dmax != 0.0f) *nonempty += 1u;
    }
  }
  it->t0 = e;
  majorant_iterator_segment(scene, it, seg);
}

/* The segment's majorant per channel, for each medium's extinction (bound) per unit density
 * sigma_t[i]: the sum over the media of dmax * majorant_scale * sigma_t. */
inline float4 majorant_segment_sigma_maj(__constant const st_scene* scene, const st_majorant_segment* seg,
                                         const float4* sigma_t) {
  float4 sigma_maj = (float4)(0.0f);
  for (int i = 0; i < ST_KERNEL_MAX_MEDIA; ++i)
    if (i < scene->n_media && seg->dmax[i] != 0.0f) sigma_maj += seg->dmax[i] * scene->media[i].majorant_scale * sigma_t[i];
  return sigma_maj;
}

#endif
