/* queues.h: the wavefront's device queues and counters, the stage kernels' argument list
 * (ST_STAGE_ARGS), the flush of a work item's tracking statistics into the counters, and the
 * random stream of a path.
 * Every queue has two buffers (parity cur / 1 - cur); a stage reads n items of its queue in the
 * current buffer and pushes into the next buffers with atomic_inc on the next-size counters,
 * which the host reads once per iteration. Queues FREE..FINISH hold path slots (capacity Q);
 * FREE is the exception to the two buffers: one stack of free slots (free_push below).
 * SHADOW holds shadow-ray entry ids slot * NL + ring * n_lights + light (capacity Q * NL, NL =
 * n_lights * R, R the shadow ring of types.h). ST_STAGE_ARGS is the argument
 * list of every stage kernel, in the order of enum st_stage_arg (types.h), by which the host binds
 * them; `it` (st_iteration) holds the queue parity and sizes of the current iteration. */
#ifndef SPECTRACK_QUEUES_H
#define SPECTRACK_QUEUES_H

#include "types.h"
#include "features.h"
#include "rng.h"
#include "sampling.h"
#include "spectrum.h"
#include "tracking.h"
#include "guiding.h"

#define ST_STAGE_ARGS                                                                              \
  __constant const st_scene *scene, __global const uint *grids, __global const float2 *maj,       \
      __global const float *env, __global st_path *paths, __global st_shadow *shadows,            \
      __global uint *queues, __global uint *counters, __global float4 *results, uint Q, uint NL,   \
      st_iteration it, __global const st_guide_header *guide, __global uint *guide_records

inline uint queue_offset(uint Q, uint NL, uint parity, int k) {
  return parity * ((uint)ST_Q_PATH_QUEUES * Q + Q * NL) + (uint)k * Q;
}

inline void queue_push(__global uint* queues, __global uint* counters, uint Q, uint NL, uint cur, int k, uint item) {
  uint i = atomic_inc(&counters[ST_C_QUEUE + k]);
  queues[queue_offset(Q, NL, 1u - cur, k) + i] = item;
}

inline uint queue_item(__global const uint* queues, uint Q, uint NL, uint cur, int k, uint i) {
  return queues[queue_offset(Q, NL, cur, k) + i];
}

/* The free slots: one buffer (parity 0 of FREE), a stack whose size n_free the host tracks.
 * Places 0 .. n_free - 1 hold the free slots when an iteration starts; raygen, the iteration's
 * first launch, takes the top n_new (places free_base .. n_free - 1, free_base = n_free - n_new),
 * and slots freed later in the iteration (finish, on the same in-order queue, so after raygen has
 * read its places) are pushed from free_base on. The free slots after the iteration are places
 * 0 .. free_base + (pushes) - 1, which the host reads back as the FREE counter. */
inline uint free_offset(uint Q) { return (uint)ST_Q_FREE * Q; /* parity 0 */ }
inline uint free_base(uint n_free, uint n_new) { return n_free - n_new; }
inline void free_push(__global uint* queues, __global uint* counters, uint Q, uint base, uint slot) {
  uint i = atomic_inc(&counters[ST_C_QUEUE + ST_Q_FREE]);
  queues[free_offset(Q) + base + i] = slot;
}

/* Adaptive sampling (ST_FEATURE_ADAPTIVE): after both parities of the queues, the list of the
 * window pixels (row-major indices in the window) whose samples this render draws; a batch is
 * whole samples of these pixels, in list order. */
inline uint active_pixels_offset(uint Q, uint NL) { return 2u * ((uint)ST_Q_PATH_QUEUES * Q + Q * NL); }

inline void counter_add(__global uint* counters, int c, uint v) {
  if (v) atomic_add(&counters[c], v);
}

inline void flush_track_stats(__global uint* counters, const st_track_stats* st, int lookup_counter) {
  counter_add(counters, lookup_counter, st->lookups);
  counter_add(counters, ST_C_LOOKUPS_EMISSION, st->emission_lookups);
  counter_add(counters, ST_C_REAL_COLLISIONS, st->real);
  counter_add(counters, ST_C_NULL_COLLISIONS, st->nulls);
  counter_add(counters, ST_C_CONTROL_COLLISIONS, st->control);
  counter_add(counters, ST_C_RESIDUAL_COLLISIONS, st->residual);
  counter_add(counters, ST_C_DDA_STEPS, st->dda_steps);
  counter_add(counters, ST_C_DDA_NONEMPTY, st->dda_nonempty);
  if (st->max_beta > 0.0f) atomic_max(&counters[ST_C_MAX_THROUGHPUT_BITS], as_uint(st->max_beta));
}

/* ---- shadow-ray entries (types.h st_shadow) ----
 * A path's shadow rays of bounce d use the entries slot * NL + (d % R) * n_lights + l, R = NL /
 * n_lights the ring (shadow_ring). When one finishes, k_shadow marks it done; its weight * T is
 * added to its light's accumulator (the Ls of entry slot * NL + l) by the path itself, when it
 * needs the entry again (k_scatter, R bounces later) or when it finishes (k_finish, the remaining entries oldest
 * first), which leaves every entry of the slot empty for the next path (the host clears the
 * buffer once). So each accumulator has one writer and adds its terms in bounce order: the sums,
 * and the image, do not depend on the order in which shadow rays finish. */
inline int shadow_ring(uint NL, int n_lights) { return n_lights > 0 ? (int)(NL / (uint)n_lights) : 1; }
inline uint shadow_entry(uint slot, uint NL, int n_lights, int bounce, int light) {
  return slot * NL + (uint)(bounce % shadow_ring(NL, n_lights)) * (uint)n_lights + (uint)light;
}

/* Adds finished entry e, of bounce `bounce`, to its light's accumulator acc and empties it; the
 * first scattering event's shadow rays also go to the direct pass (types.h ST_AOVS) of the path's
 * result `r` (its first float4 in the batch result buffer). A shadow catcher's entry (ground.h)
 * goes to the shadow layer only. */
inline void shadow_fold(__constant const st_scene* scene, __global st_shadow* acc, __global st_shadow* e, int bounce,
                        __global float4* r) {
  const float4 c = e->weight * e->tr.T;
  if (ST_HAS_GROUND && e->catcher) {
    r[ST_RESULT_SHADOW] += c;
    e->state = ST_SHADOW_EMPTY;
    return;
  }
  acc->Ls += c;
  if (ST_HAS_AOV && scene->result_layers > ST_RESULT_LAYERS_AOV && bounce == 0) r[ST_RESULT_DIRECT] += c;
  e->state = ST_SHADOW_EMPTY;
}

/* Spectral mode (st_film_color): the four wavelengths of sample (pixel, sample), shared by the
 * paths of a per-channel tracker's sample, from the first draw of a stream of their own
 * (ST_STREAM_WAVELENGTHS on channel 0), so they depend only on the seed, pixel and sample.
 * raygen.cl draws them once into st_path.lambda (a Philox call and four inverse CDFs that every
 * kernel call repeated before). */
inline float4 path_wavelengths(__constant const st_scene* scene, const st_path* p) {
  st_rng r = rng_make(scene->seed, p->pixel, p->sample, 0u, ST_STREAM_WAVELENGTHS, 0u);
  return sample_wavelengths(rng_uniform(&r), 4);
}

/* The time of sample (pixel, sample) in the shutter, as a fraction u in [0, 1) of it (the time
 * is open + u (close - open), st_camera.shutter): the pixel's N samples (shutter.z) are
 * stratified, sample s in stratum s mod N with a uniform offset inside it, and the strata are
 * rotated by a uniform per pixel (Cranley-Patterson), so every sample's u is uniform on its own and
 * a pixel's N samples cover the shutter evenly. Draws 0 and 1 of the stream ST_STREAM_TIME of
 * (pixel, sample) and of (pixel, 0) on channel 0: the time depends only on the seed, pixel and
 * sample, so the paths of a per-channel tracker's sample share it and shards merge exactly. */
inline float path_shutter_u(__constant const st_scene* scene, uint pixel, uint sample) {
  const uint N = (uint)scene->camera.shutter.z;
  st_rng r = rng_make(scene->seed, pixel, sample, 0u, ST_STREAM_TIME, 0u);
  const float xi = rng_uniform(&r);
  st_rng r0 = rng_make(scene->seed, pixel, 0u, 0u, ST_STREAM_TIME, 1u);
  const float rotation = rng_uniform(&r0);
  const float u = ((float)(sample % N) + xi) / (float)N + rotation;
  return fmin(u - floor(u), 0x1.fffffep-1f);
}

/* The time of sample (pixel, sample) in seconds: open + u (close - open) (0 without a shutter). */
inline float path_time(__constant const st_scene* scene, uint pixel, uint sample) {
  __constant const st_camera* cam = &scene->camera;
  if (!(cam->shutter.z > 0.0f)) return 0.0f;
  return mix(cam->shutter.x, cam->shutter.y, path_shutter_u(scene, pixel, sample));
}

/* The lanes a path carries: its own lane for a per-channel tracker, else every lane of the scene. */
inline float4 path_mask(__constant const st_scene* scene, const st_path* p) {
  return scene->n_channels_per_sample > 1 ? one_hot((int)p->channel) : scene_lanes(scene);
}

/* The random stream of a path (stream 0) or of one of its shadow rays. */
inline st_rng path_rng(__constant const st_scene* scene, const st_path* p, uint stream, uint draw) {
  st_rng r = rng_make(scene->seed, p->pixel, p->sample, p->channel, stream, draw);
  if (spectral_mode(scene)) r.lambda = p->lambda;
  if (ST_HAS_VELOCITY) r.time = path_time(scene, p->pixel, p->sample);
  return r;
}

#endif
