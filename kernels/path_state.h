/* path_state.h: the schema of the path state (st_path), one slot per path in flight. Part of
 * types.h (included where st_path is declared); include types.h, not this file.
 *
 * Design: ST_PATH_FIELDS is the one list of the state's fields, X(PATH, type, name, group); from it
 * come (state_schema.h) the struct st_path (the layout of one slot, its size checked on both
 * sides), the byte offsets of the structure-of-arrays layout and the kernels' group-wise loads and
 * stores. Two layouts of the same buffer of Q * sizeof(st_path) bytes, chosen by the kernel define
 * ST_STATE_SOA (the host's choice per device type, src/integrator/state_layout.h):
 *   AoS (no define): slot i is st_path i, its fields side by side (one cache line on a CPU);
 *   SoA (ST_STATE_SOA): one array per field, field f of slot i at byte
 *        Q * st_path_field_offset(f) + i * sizeof(f) (a GPU's warp reads 32 neighbouring values).
 * A kernel copies the groups it uses into a private st_path (path_load) and writes back the groups
 * it changes (path_store); the other fields stay unread and unwritten, which keeps them out of
 * the registers of the tracking and shadow kernels. The groups:
 *   TRACK:    the ray, throughput, spectral-MIS ratios, random draw and medium: what k_track
 *             reads and writes;
 *   KEY:      the random stream's key and the lanes (pixel, sample, channel): read by every kernel,
 *             written by raygen;
 *   SPECTRUM: the wavelengths (spectral mode; 0 in rgb mode): written by raygen;
 *   RADIANCE: what the path gathered: emission (k_track), escape, finish;
 *   VERTEX:   the result index, depth and pending shadow rays: scatter, escape, finish, and k_track
 *             only with the layers, a ground or a sphere light. */
#ifndef SPECTRACK_PATH_STATE_H
#define SPECTRACK_PATH_STATE_H

#include "state_schema.h"

enum st_path_group {
  ST_PATH_TRACK = 1,
  ST_PATH_KEY = 2,
  ST_PATH_SPECTRUM = 4,
  ST_PATH_RADIANCE = 8,
  ST_PATH_VERTEX = 16,
  ST_PATH_ALL = 31
};

/* X(PATH, type, name, group), in the order of the AoS struct. */
#define ST_PATH_FIELDS(X)                                                                                         \
  X(PATH, st_float4, o, TRACK)           /* xyz: ray origin; w: t reached along the ray (resume point) */        \
  X(PATH, st_float4, d, TRACK)           /* xyz: unit direction; w: pdf of the phase sample that made d (0: camera ray) */ \
  X(PATH, st_float4, beta, TRACK)        /* throughput weight per channel */                                      \
  X(PATH, st_float4, L, RADIANCE)        /* radiance gathered by this path (emission, escape) */                  \
  X(PATH, st_float4, r_u, TRACK)         /* spectral-mis: each channel's path pdf over the hero's, mean 1 (tracking.h) */ \
  X(PATH, st_uint, pixel, KEY)           /* pixel index in the film window */                                     \
  X(PATH, st_uint, sample, KEY)          /* sample index in the full sequence */                                  \
  X(PATH, st_uint, channel, KEY)         /* delta-per-channel: its lane (0..2, spectral 0..3); spectral-mis: the hero lane */ \
  X(PATH, st_uint, result_index, VERTEX) /* slot in the batch result buffer */                                    \
  X(PATH, st_uint, rng_draw, TRACK)      /* next draw of the path's random stream */                              \
  X(PATH, st_int, depth, VERTEX)         /* real scattering events so far */                                      \
  X(PATH, st_int, pending, VERTEX)       /* shadow rays of this path not finished yet (k_shadow: atomic_dec) */   \
  X(PATH, st_int, medium, TRACK)         /* medium whose phase function applies at the scatter point */           \
  X(PATH, st_float4, lambda, SPECTRUM)   /* spectral mode: the sample's four wavelengths (nm, queues.h path_wavelengths); rgb: 0 */
/* (a path's batch ring slot is result_index / st_iteration.batch_paths; the lanes it carries are
 * not stored either: queues.h path_mask) */

typedef struct {
  ST_PATH_FIELDS(ST_X_STATE_MEMBER)
} st_path;

ST_STATE_SCHEMA(PATH, path) /* enum st_path_field, st_path_field_offset */

/* Checked at the end of types.h: the fields fill st_path without padding (so the SoA arrays fill
 * the same buffer), each at its AoS offset and aligned to its size (so every SoA array is). */
#ifdef __OPENCL_VERSION__
#define ST_CHECK_PATH_LAYOUT ST_STATE_CHECK_BYTES(PATH, path, ST_SIZEOF_PATH)
#else
#define ST_X_PATH_CHECK(S, type, name, group)                                          \
  static_assert(st_path_field_offset(ST_PATH_F_##name) == offsetof(st_path, name) &&    \
                    st_path_field_offset(ST_PATH_F_##name) % sizeof(type) == 0,         \
                "st_path." #name " offset");
#define ST_CHECK_PATH_LAYOUT ST_STATE_CHECK_BYTES(PATH, path, ST_SIZEOF_PATH) ST_PATH_FIELDS(ST_X_PATH_CHECK)
#endif

#ifdef __OPENCL_VERSION__
/* The path buffer (SoA: as words); field `name` of slot i: SoA in its own array, AoS the member. */
#define ST_PATH_STATE ST_STATE_BUFFER(st_path)
#ifdef ST_STATE_SOA
#define ST_PATH_FIELD(state, Q, i, type, name) ST_STATE_SOA_AT(state, Q, i, type, st_path_field_offset(ST_PATH_F_##name))
#else
#define ST_PATH_FIELD(state, Q, i, type, name) ((state)[i].name)
#endif

/* Copies the fields of `groups` (st_path_group bits, a constant) of slot i into *p. */
inline void path_load(ST_PATH_STATE state, uint n, uint i, uint groups, st_path* p) {
  ST_PATH_FIELDS(ST_X_STATE_LOAD)
}

/* Writes the fields of `groups` of *p to slot i. */
inline void path_store(ST_PATH_STATE state, uint n, uint i, uint groups, const st_path* p) {
  ST_PATH_FIELDS(ST_X_STATE_STORE)
}

/* The pending count of slot `slot` in place (k_shadow decrements it atomically). */
inline __global int* path_pending(ST_PATH_STATE state, uint Q, uint slot) {
  return &ST_PATH_FIELD(state, Q, slot, st_int, pending);
}
#endif

#endif /* SPECTRACK_PATH_STATE_H */
