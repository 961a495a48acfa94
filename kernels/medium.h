/* medium.h: what a point of the scene is made of. A medium offers a density lookup at a world
 * point (trilinear through PNanoVDB for VDB media, or one voxel of the trilinear support chosen
 * at random: st_lookup_mode; 1 inside the box for homogeneous media) and its per-unit-density
 * coefficients; overlapping media add their coefficients.
 *
 * Index space: a VDB medium's world_to_index maps world points to NanoVDB index coordinates
 * (values at integer coordinates; trilinear between floor(p) and floor(p)+1, inactive voxels
 * read 0). A homogeneous medium's world_to_index maps its bounds onto [0,1]^3, its majorant
 * grid has one cell, and its density is 1 inside. Every medium's extent is its majorant-grid box.
 *
 * Motion blur (Eulerian, first order, as Arnold's and Cycles' forks): a VDB medium with a velocity
 * grid v (st_medium.velocity_grid) is looked up at time t (the path's, st_rng.time) at x - v(x) t:
 * density, emission, temperature and colour at the point the flow carries to x by time t, with
 * v read once at x (no integration along the flow, so curved flows blur along straight lines).
 * The velocity's 3 lookups count as density lookups. Each majorant cell of a moving medium grows
 * by the largest displacement of a lookup from inside it (src/scene/pack_velocity.cpp,
 * build_majorant_grid's cell_reach), so it bounds every point its lookups can reach during the
 * shutter.
 */
#ifndef SPECTRACK_MEDIUM_H
#define SPECTRACK_MEDIUM_H

#include "types.h"
#include "features.h"
#include "rng.h"
#include "spectrum.h"
#include "pnanovdb_cl.h"

inline float3 medium_to_index(__constant const st_medium* m, float3 p) {
  float4 q = (float4)(p, 1.0f);
  return (float3)(dot(m->world_to_index[0], q), dot(m->world_to_index[1], q), dot(m->world_to_index[2], q));
}
inline float3 medium_dir_to_index(__constant const st_medium* m, float3 d) {
  float4 q = (float4)(d, 0.0f);
  return (float3)(dot(m->world_to_index[0], q), dot(m->world_to_index[1], q), dot(m->world_to_index[2], q));
}

inline int medium_box_contains(__constant const st_medium* m, float3 pi) {
  float3 lo = m->maj_origin.xyz;
  float3 hi = lo + m->maj_origin.w * convert_float3((int3)(m->maj_dims[0], m->maj_dims[1], m->maj_dims[2]));
  return all(pi >= lo) && all(pi < hi);
}

/* Where the index-space ray (oi, di) (di without -0.0 components) enters and leaves medium m's
 * box: *t_enter >= *t_exit when it misses. */
inline void medium_box_interval(__constant const st_medium* m, float3 oi, float3 di, float* t_enter, float* t_exit) {
  float3 lo = m->maj_origin.xyz;
  float3 hi = lo + m->maj_origin.w * convert_float3((int3)(m->maj_dims[0], m->maj_dims[1], m->maj_dims[2]));
  float3 inv = 1.0f / di;
  float3 t0 = (lo - oi) * inv, t1 = (hi - oi) * inv;
  float3 tmin = fmin(t0, t1), tmax = fmax(t0, t1);
  /* axis-parallel rays: inside the slab -> (-inf, inf); outside -> empty (+inf, -inf). Set on the
   * interval itself: an empty (t0, t1) = (+inf, -inf) would be swapped into the whole line by the
   * fmin / fmax above, which made rays beside a box (orthographic cameras along an axis) walk it:
   * null collisions only for tracking, but the decomposition trackers' control attenuated them. */
  int3 par = di == 0.0f;
  int3 in_slab = (oi >= lo) & (oi < hi);
  tmin = select(tmin, select((float3)(INFINITY), (float3)(-INFINITY), in_slab), par);
  tmax = select(tmax, select((float3)(-INFINITY), (float3)(INFINITY), in_slab), par);
  *t_enter = fmax(fmax(tmin.x, tmin.y), tmin.z);
  *t_exit = fmin(fmin(tmax.x, tmax.y), tmax.z);
}

/* Spectral mode (st_medium.spectral): the coefficients and emission are spectra, evaluated at the
 * path's wavelengths (kernels/spectrum.h); otherwise the rgb values themselves. */
inline int medium_is_spectral(__constant const st_medium* m) { return ST_HAS_SPECTRAL && m->spectral; }
inline float4 medium_sigma_a(__constant const st_medium* m, float4 lambda) {
  return medium_is_spectral(m) ? spectrum_at(m->sigma_a, lambda) : m->sigma_a;
}
inline float4 medium_sigma_s(__constant const st_medium* m, float4 lambda) {
  return medium_is_spectral(m) ? spectrum_at(m->sigma_s, lambda) : m->sigma_s;
}

/* A read accessor of the NanoVDB float grid at word offset `offset` of the grid buffer. */
inline pnanovdb_readaccessor_t grid_accessor(__global const uint* grids, uint offset, pnanovdb_buf_t* buf) {
  buf->data = grids + offset;
  pnanovdb_grid_handle_t grid = {pnanovdb_address_null()};
  pnanovdb_tree_handle_t tree = pnanovdb_grid_get_tree(*buf, grid);
  pnanovdb_root_handle_t root = pnanovdb_tree_get_root(*buf, tree);
  pnanovdb_readaccessor_t acc;
  pnanovdb_readaccessor_init(&acc, root);
  return acc;
}

/* Trilinear value of a NanoVDB float grid at continuous index point pi.
 * Fast path (7 in 8 points per axis, 67% of all): when the lower corner lies in a leaf node and
 * the 2x2x2 block does not cross that leaf's faces, the eight values are read at fixed offsets
 * from the first one (a float leaf stores all 512 values densely, voxel (x, y, z) & 7 at index
 * x * 64 + y * 8 + z, 4 bytes each: PNanoVDB's pnanovdb_leaf_coord_to_offset and
 * leaf_get_table_address), instead of seven more accessor walks. The same values, so the same
 * image, either way. */
inline float grid_trilinear(__global const uint* grids, uint offset, float3 pi) {
  pnanovdb_buf_t buf;
  pnanovdb_readaccessor_t acc = grid_accessor(grids, offset, &buf);
  float3 fl = floor(pi);
  float3 f = pi - fl;
  int3 i0 = convert_int3(fl);
  float v[8];
  pnanovdb_coord_t ijk0;
  ijk0.x = i0.x;
  ijk0.y = i0.y;
  ijk0.z = i0.z;
  pnanovdb_uint32_t level;
  pnanovdb_address_t a0 = pnanovdb_readaccessor_get_value_address_and_level(PNANOVDB_GRID_TYPE_FLOAT, buf, &acc, &ijk0, &level);
  if (level == 0u && (i0.x & 7) != 7 && (i0.y & 7) != 7 && (i0.z & 7) != 7) {
    for (int c = 0; c < 8; ++c) {
      uint n = (uint)(c & 1) * 64u + (uint)((c >> 1) & 1) * 8u + (uint)((c >> 2) & 1);
      v[c] = pnanovdb_read_float(buf, pnanovdb_address_offset(a0, 4u * n));
    }
  } else {
    v[0] = pnanovdb_read_float(buf, a0);
    for (int c = 1; c < 8; ++c) {
      pnanovdb_coord_t ijk;
      ijk.x = i0.x + (c & 1);
      ijk.y = i0.y + ((c >> 1) & 1);
      ijk.z = i0.z + ((c >> 2) & 1);
      pnanovdb_address_t a = pnanovdb_readaccessor_get_value_address(PNANOVDB_GRID_TYPE_FLOAT, buf, &acc, &ijk);
      v[c] = pnanovdb_read_float(buf, a);
    }
  }
  float x00 = mix(v[0], v[1], f.x), x10 = mix(v[2], v[3], f.x);
  float x01 = mix(v[4], v[5], f.x), x11 = mix(v[6], v[7], f.x);
  return mix(mix(x00, x10, f.y), mix(x01, x11, f.y), f.z);
}

/* Stochastic one-voxel lookup (st_lookup_mode "stochastic"; docs/stochastic-lookup.md): the value
 * of one voxel of the 2x2x2 trilinear support of pi, voxel (i0 + b) chosen with probability equal
 * to its trilinear weight prod_a (b_a ? f_a : 1 - f_a), so its expectation is grid_trilinear's
 * value. One uniform u makes the three binary choices in turn: each compares u with the axis'
 * weight and rescales it onto the chosen side, which is a partition of [0, 1) into the 8 weights'
 * intervals, so each voxel's probability is its weight to the uniform's resolution (2^-24) and
 * float rounding, as exact as the trilinear blend itself. A rescaled u that rounds up to 1 is
 * kept below 1 (with f = 1.0f on the next axis, 1 - f = 0 would otherwise give 0/0). One accessor
 * walk, one read. */
inline float grid_stochastic(__global const uint* grids, uint offset, float3 pi, float u) {
  pnanovdb_buf_t buf;
  pnanovdb_readaccessor_t acc = grid_accessor(grids, offset, &buf);
  float3 fl = floor(pi);
  float3 f = pi - fl;
  int3 i = convert_int3(fl);
  const float below_one = 0.99999994f; /* the float below 1 */
  if (u < f.x) i.x += 1, u = u / f.x;
  else u = (u - f.x) / (1.0f - f.x);
  u = fmin(u, below_one);
  if (u < f.y) i.y += 1, u = u / f.y;
  else u = (u - f.y) / (1.0f - f.y);
  u = fmin(u, below_one);
  if (u < f.z) i.z += 1;
  pnanovdb_coord_t ijk;
  ijk.x = i.x;
  ijk.y = i.y;
  ijk.z = i.z;
  return pnanovdb_read_float(buf, pnanovdb_readaccessor_get_value_address(PNANOVDB_GRID_TYPE_FLOAT, buf, &acc, &ijk));
}

/* The addresses of the 8 corner values of a NanoVDB Vec3f grid's trilinear support at voxel i0
 * (corner k at i0 + (k & 1, (k >> 1) & 1, k >> 2)), through the caller's accessor. When the 2x2x2
 * block lies in one leaf (grid_trilinear's fast path) they sit at fixed offsets from the first: a
 * Vec3f leaf stores its 512 values densely, 12 bytes each, voxel (x, y, z) & 7 at index
 * x * 64 + y * 8 + z; otherwise each corner walks the accessor (its cached nodes make that cheap). */
inline void vec3_corners(pnanovdb_buf_t buf, pnanovdb_readaccessor_t* acc, int3 i0, pnanovdb_address_t* a) {
  pnanovdb_coord_t ijk;
  ijk.x = i0.x;
  ijk.y = i0.y;
  ijk.z = i0.z;
  pnanovdb_uint32_t level;
  a[0] = pnanovdb_readaccessor_get_value_address_and_level(PNANOVDB_GRID_TYPE_VEC3F, buf, acc, &ijk, &level);
  const int one_leaf = level == 0u && (i0.x & 7) != 7 && (i0.y & 7) != 7 && (i0.z & 7) != 7;
  for (int k = 1; k < 8; ++k) {
    if (one_leaf) {
      const uint n = (uint)(k & 1) * 64u + (uint)((k >> 1) & 1) * 8u + (uint)((k >> 2) & 1);
      a[k] = pnanovdb_address_offset(a[0], 12u * n);
      continue;
    }
    ijk.x = i0.x + (k & 1);
    ijk.y = i0.y + ((k >> 1) & 1);
    ijk.z = i0.z + ((k >> 2) & 1);
    a[k] = pnanovdb_readaccessor_get_value_address(PNANOVDB_GRID_TYPE_VEC3F, buf, acc, &ijk);
  }
}

/* The trilinear value at index point q of a NanoVDB Vec3f grid, through the caller's accessor. */
inline float3 vec3_trilinear(pnanovdb_buf_t buf, pnanovdb_readaccessor_t* acc, float3 q) {
  const float3 fl = floor(q), f = q - fl;
  pnanovdb_address_t a[8];
  vec3_corners(buf, acc, convert_int3(fl), a);
  float3 v[8];
  for (int k = 0; k < 8; ++k)
    v[k] = (float3)(pnanovdb_read_float(buf, a[k]), pnanovdb_read_float(buf, pnanovdb_address_offset(a[k], 4u)),
                    pnanovdb_read_float(buf, pnanovdb_address_offset(a[k], 8u)));
  const float3 x00 = mix(v[0], v[1], f.x), x10 = mix(v[2], v[3], f.x);
  const float3 x01 = mix(v[4], v[5], f.x), x11 = mix(v[6], v[7], f.x);
  return mix(mix(x00, x10, f.y), mix(x01, x11, f.y), f.z);
}

/* The trilinear value of component c (0, 1, 2) alone at index point q of a NanoVDB Vec3f grid. */
inline float vec3_component_trilinear(pnanovdb_buf_t buf, pnanovdb_readaccessor_t* acc, float3 q, uint c) {
  const float3 fl = floor(q), f = q - fl;
  pnanovdb_address_t a[8];
  vec3_corners(buf, acc, convert_int3(fl), a);
  float v[8];
  for (int k = 0; k < 8; ++k) v[k] = pnanovdb_read_float(buf, pnanovdb_address_offset(a[k], 4u * c));
  const float x00 = mix(v[0], v[1], f.x), x10 = mix(v[2], v[3], f.x);
  const float x01 = mix(v[4], v[5], f.x), x11 = mix(v[6], v[7], f.x);
  return mix(mix(x00, x10, f.y), mix(x01, x11, f.y), f.z);
}

/* The index point whose values medium m shows at world-index point pi at time t (seconds):
 * pi - velocity_to_index v(pi) t, with v the velocity grid's (a NanoVDB Vec3f grid) trilinear value
 * at pi, or for a staggered grid each component a at pi + 1/2 along axis a (OpenVDB's
 * StaggeredBoxSampler), all through one accessor (one tree walk); pi itself for a medium that
 * does not move. Counts as 3 lookups. */
inline float3 medium_lookup_index(__constant const st_medium* m, __global const uint* grids, float3 pi, float t,
                                  uint* lookups) {
  if (!ST_HAS_VELOCITY || m->velocity_grid[0] == ST_NO_GRID) return pi;
  pnanovdb_buf_t buf;
  pnanovdb_readaccessor_t acc = grid_accessor(grids, m->velocity_grid[0], &buf);
  float3 v;
  if (m->velocity_grid[3]) {
    v.x = vec3_component_trilinear(buf, &acc, pi + (float3)(0.5f, 0.0f, 0.0f), 0u);
    v.y = vec3_component_trilinear(buf, &acc, pi + (float3)(0.0f, 0.5f, 0.0f), 1u);
    v.z = vec3_component_trilinear(buf, &acc, pi + (float3)(0.0f, 0.0f, 0.5f), 2u);
  } else {
    v = vec3_trilinear(buf, &acc, pi);
  }
  const float4 vt = (float4)(v * t, 0.0f);
  *lookups += 3u;
  return pi - (float3)(dot(m->velocity_to_index[0], vt), dot(m->velocity_to_index[1], vt),
                       dot(m->velocity_to_index[2], vt));
}

inline int lookup_is_stochastic(__constant const st_scene* scene) {
  return ST_HAS_STOCHASTIC_LOOKUP && scene->lookup == ST_LOOKUP_STOCHASTIC;
}

/* Density of medium m at world point p at time t (0 outside its box). Counts one lookup for VDB
 * media (and a moving medium's velocity lookups). rng: the caller's stream, drawn once per VDB
 * lookup when lookups are stochastic (scene->lookup), never otherwise. */
inline float medium_density(__constant const st_scene* scene, __constant const st_medium* m, __global const uint* grids,
                            float3 p, float t, uint* lookups, st_rng* rng) {
  float3 pi = medium_to_index(m, p);
  if (!medium_box_contains(m, pi)) return 0.0f;
  if (!ST_HAS_VDB) return 1.0f; /* homogeneous media only */
  if (m->type == ST_MEDIUM_HOMOGENEOUS) return 1.0f;
  pi = medium_lookup_index(m, grids, pi, t, lookups);
  *lookups += 1u;
  if (lookup_is_stochastic(scene)) return grid_stochastic(grids, m->density_grid, pi, rng_uniform(rng));
  return grid_trilinear(grids, m->density_grid, pi);
}

/* Where temperature T falls in medium m's blackbody table (the grid buffer at blackbody_offset):
 * entry *i and the fraction towards entry *i + 1, linear in the warped temperature
 * w = A / T - B ln T (src/color/blackbody.h), clamped to the table. */
inline float blackbody_table_pos(__constant const st_medium* m, float T, uint* i) {
  const float w = m->temperature.w / T - m->blackbody_table.w * log(T);
  const float last = m->blackbody_table.z;
  const float u = clamp((w - m->blackbody_table.x) * m->blackbody_table.y, 0.0f, last);
  *i = min((uint)u, (uint)last - 1u);
  return u - (float)*i;
}

/* The blackbody colour (linear sRGB, unscaled) of a temperature grid value v: T = v * a + b
 * (a = temperature_scale, b = -temperature_offset * temperature_scale), 0 at or below the
 * cutoff, else the table's colours interpolated between its two nearest entries. */
inline float4 blackbody_rgb(__constant const st_medium* m, __global const uint* grids, float v) {
  const float T = v * m->temperature.x + m->temperature.y;
  if (!(T > m->temperature.z)) return (float4)(0.0f);
  uint i;
  const float f = blackbody_table_pos(m, T, &i);
  __global const float* t = (__global const float*)(grids + m->blackbody_offset) + 4u * i;
  const float4 a = vload4(0, t), b = vload4(1, t);
  return (float4)(mix(a.xyz, b.xyz, f), 0.0f);
}

/* Spectral mode's blackbody emission at p (m->blackbody, types.h): m->Le.x B(lambda, T) / N(T)
 * at the path's wavelengths, Planck's law evaluated exactly per wavelength (kernels/spectrum.h);
 * T is the temperature grid's value mapped as in blackbody_rgb (0 at or below the cutoff) or the
 * constant temperature.y, raised to the table's floor; ln N is interpolated from the table's lane w,
 * or the constant's blackbody_log_norm. */
inline float4 blackbody_spectral_Le(__constant const st_medium* m, __global const uint* grids, float3 p, float t,
                                    uint* lookups, float4 lambda) {
  float T = m->temperature.y, log_norm = m->blackbody_log_norm;
  if (m->emission_grid != ST_NO_GRID) {
    const float3 pi = medium_lookup_index(m, grids, medium_to_index(m, p), t, lookups);
    *lookups += 1u;
    T = grid_trilinear(grids, m->emission_grid, pi) * m->temperature.x + m->temperature.y;
    if (!(T > m->temperature.z)) return (float4)(0.0f);
    uint i;
    const float f = blackbody_table_pos(m, T, &i);
    __global const float* t = (__global const float*)(grids + m->blackbody_offset) + 4u * i;
    log_norm = mix(t[3], t[7], f);
  }
  T = fmax(T, ST_BLACKBODY_T_FLOOR);
  return m->Le.x * blackbody_over_norm(lambda, T, log_norm);
}

/* Emitted radiance Le of medium m at p at time t: radiance * scale (* the emission grid's value),
 * or scale * the blackbody colour of the temperature grid's value (emission type "blackbody"); in
 * spectral mode at the path's wavelengths. */
inline float4 medium_Le(__constant const st_medium* m, __global const uint* grids, float3 p, float t, uint* lookups,
                        float4 lambda) {
  if (!ST_HAS_EMISSION || !m->emissive) return (float4)(0.0f);
  if (ST_HAS_SPECTRAL && m->blackbody) return blackbody_spectral_Le(m, grids, p, t, lookups, lambda);
  const float4 Le = medium_is_spectral(m) ? illuminant_at(m->Le, lambda) : m->Le;
  if (m->emission_grid == ST_NO_GRID) return Le;
  float3 pi = medium_lookup_index(m, grids, medium_to_index(m, p), t, lookups);
  *lookups += 1u;
  const float v = grid_trilinear(grids, m->emission_grid, pi);
  if (m->blackbody_offset != ST_NO_GRID) return Le * blackbody_rgb(m, grids, v);
  return Le * v;
}

/* ---- colour grids (st_color_mode) ----
 * A VDB medium may carry a vec3 colour grid C (three float grids in the density grid's index
 * space; inactive voxels read the file's background). Its coefficients per unit density at p are
 *   albedo:     sigma_s = sigma_t * clamp(C(p), 0, 1), sigma_a = sigma_t - sigma_s, where
 *               sigma_t = m->sigma_a + m->sigma_s: the extinction, and so every majorant and
 *               minorant, is the colour-free one;
 *   scattering: sigma_s = m->sigma_s * max(C(p), 0), sigma_a = m->sigma_a: the extinction per
 *               unit density is bounded by m->sigma_t_maj = sigma_a + sigma_s * max C (the host
 *               takes the maximum over the grid's values and its background).
 * A medium with a colour grid has no control component (walker.h tracker_segment): its
 * coefficients are not constant anywhere, so every collision it takes part in is a residual one,
 * which looks C up. The colour of each medium at a collision travels with the collision (tint).
 * Transmittance needs only sigma_t, so shadow rays through an albedo grid never read it.
 * Spectral mode: C becomes a spectrum at each collision, through the RGB-to-spectrum table the host
 * puts in the grid buffer at color_grid[3] (a word holding res, then kernels/spectrum.h's layout):
 * an albedo's of clamp(C, 0, 1), within [0, 1] at every wavelength, or a scattering factor's of
 * max(C, 0) in pbrt-v4's unbounded form (the spectrum of C / (2 max C), times 2 max C), which is at
 * most 2 max C; the host keeps that factor's bound in sigma_t_maj.x (1 for albedo; st_walker). */
inline int medium_has_color(__constant const st_medium* m) { return ST_HAS_COLOR && m->color_mode != ST_COLOR_NONE; }

/* C at world point p at time t (3 lookups). */
inline float4 medium_color(__constant const st_medium* m, __global const uint* grids, float3 p, float t, uint* lookups) {
  float3 pi = medium_lookup_index(m, grids, medium_to_index(m, p), t, lookups);
  *lookups += 3u;
  return (float4)(grid_trilinear(grids, m->color_grid[0], pi), grid_trilinear(grids, m->color_grid[1], pi),
                  grid_trilinear(grids, m->color_grid[2], pi), 0.0f);
}

/* Spectral mode: the spectrum of colour C (tint) at the path's wavelengths (see above). */
inline float4 medium_color_spectrum(__constant const st_medium* m, __global const uint* grids, float4 tint,
                                    float4 lambda) {
  __global const uint* t = grids + m->color_grid[3];
  float3 c = tint.xyz;
  float k = 1.0f;
  if (m->color_mode != ST_COLOR_ALBEDO) {
    c = fmax(c, (float3)(0.0f));
    const float top = fmax(c.x, fmax(c.y, c.z));
    if (!(top > 0.0f)) return (float4)(0.0f);
    k = 2.0f * top;
    c = c / k;
  }
  return k * spectrum_at(rgb2spec_lookup((__global const float*)(t + 1), (int)t[0], c), lambda);
}

/* Coefficients per unit density of medium m with colour tint (ignored without a colour grid), at
 * the path's wavelengths in spectral mode. */
inline void medium_unit_coeffs(__constant const st_medium* m, __global const uint* grids, float4 tint, float4 lambda,
                               float4* sigma_a, float4* sigma_s) {
  if (medium_has_color(m)) {
    if (medium_is_spectral(m)) {
      const float4 C = medium_color_spectrum(m, grids, tint, lambda);
      *sigma_a = spectrum_at(m->sigma_a, lambda);
      *sigma_s = spectrum_at(m->sigma_s, lambda);
      if (m->color_mode == ST_COLOR_ALBEDO) {
        const float4 sigma_t = *sigma_a + *sigma_s;
        *sigma_s = sigma_t * C;
        *sigma_a = fmax(sigma_t - *sigma_s, 0.0f);
      } else {
        *sigma_s *= C;
      }
      return;
    }
    if (m->color_mode == ST_COLOR_ALBEDO) {
      float4 sigma_t = m->sigma_a + m->sigma_s;
      *sigma_s = sigma_t * clamp(tint, 0.0f, 1.0f);
      *sigma_a = fmax(sigma_t - *sigma_s, 0.0f);
    } else {
      *sigma_s = m->sigma_s * fmax(tint, 0.0f);
      *sigma_a = m->sigma_a;
    }
    return;
  }
  *sigma_a = medium_sigma_a(m, lambda);
  *sigma_s = medium_sigma_s(m, lambda);
}

/* ---- the point sampler ----
 * What the medium is at a point, for the trackers (pbrt-v4's SamplePoint): the coefficients per
 * channel, summed over the media, and each medium's density and colour tint there, from which a
 * tracker chooses the phase function of a scattering event (tracking.h choose_scattering_medium)
 * and weighs emission, which it evaluates only where it scores it (medium_Le; emission lookups
 * are counted apart). */
typedef struct {
  float4 sigma_a, sigma_s;
  float density[ST_KERNEL_MAX_MEDIA];
  float4 tint[ST_KERNEL_MAX_MEDIA]; /* colour media: C at the point (else unused, 1) */
} st_medium_point;

/* The point sample at world point p. extinction_only: the caller needs only sigma_a + sigma_s
 * (transmittance), which an albedo grid does not change, so albedo media skip their colour lookup
 * (their sigma_a/sigma_s split is then the medium's own, the tint 1). rng: for stochastic density
 * lookups (medium_density); colour and emission grids are always read trilinearly, independently
 * of the density's voxel choice, so a product such as density x colour keeps the product of the
 * expectations. sigma_a_l, sigma_s_l: spectral media's coefficients at the path's wavelengths,
 * which the tracker caches once per walk (walker.h st_walker). */
inline st_medium_point medium_sample_point(__constant const st_scene* scene, __global const uint* grids, float3 p,
                                           uint* lookups, int extinction_only, st_rng* rng, const float4* sigma_a_l,
                                           const float4* sigma_s_l) {
  st_medium_point c;
  c.sigma_a = (float4)(0.0f);
  c.sigma_s = (float4)(0.0f);
  for (int i = 0; i < ST_KERNEL_MAX_MEDIA; ++i) {
    c.density[i] = 0.0f;
    c.tint[i] = (float4)(1.0f);
    if (i >= scene->n_media) continue;
    __constant const st_medium* m = &scene->media[i];
    float d = medium_density(scene, m, grids, p, rng->time, lookups, rng);
    c.density[i] = d;
    if (medium_has_color(m) && !(extinction_only && m->color_mode == ST_COLOR_ALBEDO)) {
      if (d == 0.0f) continue;
      c.tint[i] = medium_color(m, grids, p, rng->time, lookups);
      float4 sa, ss;
      medium_unit_coeffs(m, grids, c.tint[i], rng->lambda, &sa, &ss);
      c.sigma_a += d * sa;
      c.sigma_s += d * ss;
      continue;
    }
    c.sigma_a += d * (medium_is_spectral(m) ? sigma_a_l[i] : m->sigma_a);
    c.sigma_s += d * (medium_is_spectral(m) ? sigma_s_l[i] : m->sigma_s);
  }
  return c;
}

#endif
