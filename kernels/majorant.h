/* majorant.h: majorant segments along a ray, through every medium at once.
 *
 * Each medium has a sparse grid of (dmax, dmin) cells in its index space, walked by a 3D DDA
 * (after pbrt-v4's DDAMajorantIterator, ALGORITHMS.md 7.4). The segment iterator merges the
 * DDAs of all media: the current segment [t, end) ends at the first cell boundary or medium
 * boundary of any medium, and its majorant is the sum over media of dmax * (gray coefficient).
 * Cells with dmax = 0 give segments with zero majorant, which tracking crosses with no lookup.
 *
 * Two-level grids (sparse volumes): with maj_block = B > 0 a coarse grid of B^3-cell blocks
 * holds the max dmax (min dmin) of each block. When the DDA enters a cell whose block is empty it
 * jumps to the block's exit face in one step: the segment up to the exit has zero majorant and
 * the fine DDA resumes in the exit cell, with its face crossings recomputed from the ray (not
 * accumulated). Non-empty blocks are walked cell by cell as before. Zero-majorant segments draw
 * no random numbers, so the skip changes no estimate, only the step count.
 *
 * The DDA holds no state between launches: a path that stops (budget, scatter) restarts it at
 * its current t. That is exact because free flights restart at any point where no collision is
 * pending (memoryless property, ALGORITHMS.md 7.5). Compiled without fast/finite math, so
 * 1/0 = inf for axis-parallel rays; -0.0 components are made +0.0.
 */
#ifndef SPECTRACK_MAJORANT_H
#define SPECTRACK_MAJORANT_H

#define ST_DDA_BEFORE 0
#define ST_DDA_INSIDE 1
#define ST_DDA_DONE 2

typedef struct {
  float3 o, d;       /* ray in index space (same t as in world space) */
  float3 t_next, dt; /* next crossing per axis, crossing spacing */
  int3 cell, step;
  float t_enter, t_exit;
  float seg_end;     /* where this medium's current segment ends */
  float dmax, dmin;  /* current cell (0 outside) */
  int state;
} st_dda;

inline float2 majorant_cell(__constant const st_medium* m, __global const float2* maj, int3 c) {
  return maj[m->maj_offset + (uint)(c.x + m->maj_dims[0] * (c.y + m->maj_dims[1] * c.z))];
}

/* Index 0, 1, 2 of the smallest component (ties to the lower axis, as the DDA steps). */
inline int dda_min_axis(float3 t) {
  return (t.x <= t.y) ? ((t.x <= t.z) ? 0 : 2) : ((t.y <= t.z) ? 1 : 2);
}

/* The current cell lies in an empty coarse block [lo_c, hi_c] (fine cells): move the DDA to the
 * block's exit cell, with t_next of the exit axis at the block's exit face. */
inline void dda_skip_block(__constant const st_medium* m, st_dda* s, int3 lo_c, int3 hi_c) {
  float cs = m->maj_origin.w;
  float3 org = m->maj_origin.xyz;
  float3 face = org + convert_float3(select(lo_c, hi_c + 1, s->step > 0)) * cs;
  float3 tf = select((face - s->o) / s->d, (float3)(INFINITY), s->d == 0.0f);
  int axis = dda_min_axis(tf);
  float t_out = axis == 0 ? tf.x : (axis == 1 ? tf.y : tf.z);
  float3 p = s->o + t_out * s->d;
  int3 c = clamp(convert_int3_rtn((p - org) / cs), lo_c, hi_c);
  int3 edge = select(lo_c, hi_c, s->step > 0);
  if (axis == 0) c.x = edge.x; else if (axis == 1) c.y = edge.y; else c.z = edge.z;
  s->cell = c;
  float3 lo = org + convert_float3(c) * cs;
  float3 bound = select(lo, lo + cs, s->d > 0.0f);
  float3 tn = select((bound - s->o) / s->d, (float3)(INFINITY), s->d == 0.0f);
  if (axis == 0) tn.x = t_out; else if (axis == 1) tn.y = t_out; else tn.z = t_out;
  s->t_next = tn;
}

/* Loads (dmax, dmin) of the DDA's cell, first skipping an empty coarse block if there is one.
 * new_block: the cell may lie in another block than the previous one (only then is the coarse
 * level read). */
inline void dda_load_cell(__constant const st_medium* m, __global const float2* maj, st_dda* s, int new_block) {
  if (ST_HAS_COARSE_MAJORANT && m->maj_block > 0 && new_block) {
    int B = m->maj_block;
    int3 dims = (int3)(m->maj_dims[0], m->maj_dims[1], m->maj_dims[2]);
    int3 cdims = (dims + B - 1) / B;
    int3 blk = s->cell / B;
    float2 cv = maj[m->maj_coarse_offset + (uint)(blk.x + cdims.x * (blk.y + cdims.y * blk.z))];
    if (cv.x == 0.0f) {
      dda_skip_block(m, s, blk * B, min(blk * B + B, dims) - 1);
      s->dmax = s->dmin = 0.0f;
      return;
    }
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
  s->state = ST_DDA_INSIDE;
  dda_load_cell(m, maj, s, 1);
  s->seg_end = fmin(fmin(fmin(s->t_next.x, s->t_next.y), s->t_next.z), s->t_exit);
}

/* Starts the DDA of medium m for the world ray (o, d) at parameter t. */
inline void dda_init(__constant const st_medium* m, __global const float2* maj, st_dda* s, float3 o, float3 d, float t) {
  s->o = medium_to_index(m, o);
  s->d = medium_dir_to_index(m, d);
  s->d = select(s->d, (float3)(0.0f), s->d == 0.0f); /* -0.0 -> +0.0 */
  float3 lo = m->maj_origin.xyz;
  float3 hi = lo + m->maj_origin.w * convert_float3((int3)(m->maj_dims[0], m->maj_dims[1], m->maj_dims[2]));
  float3 inv = 1.0f / s->d;
  float3 t0 = (lo - s->o) * inv, t1 = (hi - s->o) * inv;
  /* axis-parallel rays: inside the slab -> (-inf, inf); outside -> empty */
  int3 par = s->d == 0.0f;
  int3 in_slab = (s->o >= lo) & (s->o < hi);
  t0 = select(t0, select((float3)(INFINITY), (float3)(-INFINITY), in_slab), par);
  t1 = select(t1, select((float3)(-INFINITY), (float3)(INFINITY), in_slab), par);
  float3 tmin = fmin(t0, t1), tmax = fmax(t0, t1);
  s->t_enter = fmax(fmax(tmin.x, tmin.y), tmin.z);
  s->t_exit = fmin(fmin(tmax.x, tmax.y), tmax.z);
  s->dmax = 0.0f;
  s->dmin = 0.0f;
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
  int c_axis, step_axis;
  if (axis == 0) { s->cell.x += s->step.x; s->t_next.x += s->dt.x; c_axis = s->cell.x; step_axis = s->step.x; }
  else if (axis == 1) { s->cell.y += s->step.y; s->t_next.y += s->dt.y; c_axis = s->cell.y; step_axis = s->step.y; }
  else { s->cell.z += s->step.z; s->t_next.z += s->dt.z; c_axis = s->cell.z; step_axis = s->step.z; }
  if (any(s->cell < 0) || any(s->cell >= dims)) {
    s->state = ST_DDA_DONE;
    s->seg_end = INFINITY;
    s->dmax = s->dmin = 0.0f;
    return;
  }
  /* a step enters another block only across a block face */
  int B = max(m->maj_block, 1);
  dda_load_cell(m, maj, s, (step_axis > 0) ? (c_axis % B == 0) : (c_axis % B == B - 1));
  s->seg_end = fmax(s->seg_end, fmin(fmin(fmin(s->t_next.x, s->t_next.y), s->t_next.z), s->t_exit));
}

/* The merged iterator over all media. */
typedef struct {
  st_dda m[ST_KERNEL_MAX_MEDIA];
  float t;   /* start of the current segment */
  float end; /* end of the current segment (INFINITY: no medium ahead) */
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
  s->t = t;
  segments_update_end(scene, s);
}

/* Moves to the next segment; returns the number of DDA steps taken and adds to *nonempty those
 * that entered a cell with a non-zero majorant. */
inline uint segments_next(__constant const st_scene* scene, __global const float2* maj, st_segments* s,
                          uint* nonempty) {
  uint steps = 0;
  float e = s->end;
  s->t = fmax(s->t, e);
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
  /* achromatic media: every channel holds the same sum, which is the max over any mask */
  return ST_HAS_CHROMATIC ? masked_max(m->sigma_a + m->sigma_s, mask) : m->sigma_a.x + m->sigma_s.x;
}

/* Majorant of the current segment: sum over media of dmax * majorant_scale * gray sigma_t. */
inline float segments_majorant(__constant const st_scene* scene, const st_segments* s, float4 mask) {
  float mu = 0.0f;
  for (int i = 0; i < ST_KERNEL_MAX_MEDIA; ++i) {
    if (i >= scene->n_media) continue;
    if (s->m[i].state != ST_DDA_INSIDE) continue;
    __constant const st_medium* m = &scene->media[i];
    mu += s->m[i].dmax * m->majorant_scale * medium_gray_sigma_t(m, mask);
  }
  return mu;
}

inline int segments_done(const st_segments* s) { return isinf(s->end); }

#endif
