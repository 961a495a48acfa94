/* queues.h: the wavefront's device queues and counters, the stage functions' argument lists
 * (ST_STAGE_ARGS for the kernels, ST_STAGE_PARAMS for the stage functions they wrap), the flush of
 * a work item's tracking statistics into the counters, and the random stream of a path.
 * Every queue has two buffers (parity cur / 1 - cur); a stage reads n items of its queue in the
 * current buffer and pushes into the next buffers with atomic_inc on the next-size counters,
 * which k_advance (wavefront.h) folds once per iteration on the device. The queues of path slots
 * (stage_types.h ST_STAGES, SLOTS) have capacity Q; FREE is the exception to the two buffers: one
 * stack of free slots (free_push below). SHADOW holds shadow-ray entry ids slot * NL + ring * E +
 * light (capacity Q * NL, NL = E * R, E the entries per bounce (shadow_lights), R the shadow ring
 * of types.h). ST_STAGE_ARGS is the argument list of every stage kernel, generated from
 * ST_STAGE_ARG_LIST (stage_types.h) like enum st_stage_arg, by which the host binds them; `it`
 * (st_iteration) holds the queue parity and sizes of the current iteration, which the kernels read
 * from the loop state (kernels/stages.cl). */
#ifndef SPECTRACK_QUEUES_H
#define SPECTRACK_QUEUES_H

#include "types.h"
#include "features.h"
#include "rng.h"
#include "sampling.h"
#include "spectrum.h"
#include "tracking.h"
#include "transmittance.h"
#include "guiding.h"
#include "wavefront.h"

#define ST_X_ARG_DECL(E, type, name) , type name
#define ST_X_ARG_PASS(E, type, name) , name
#define ST_STAGE_ARGS __constant const st_scene *scene ST_STAGE_ARG_LIST(ST_X_ARG_DECL)
/* A stage function's parameters: this iteration's `it`, the item gid of its queue, and the
 * kernel's arguments (ST_STAGE_FUNCTION(track) declares stage_track). */
#define ST_STAGE_PARAMS const st_iteration it, uint gid, ST_STAGE_ARGS
#define ST_STAGE_PASS(it, gid) it, gid, scene ST_STAGE_ARG_LIST(ST_X_ARG_PASS)
#define ST_STAGE_FUNCTION(stage) inline void stage_##stage(ST_STAGE_PARAMS)

/* Where queue k's buffer of parity `parity` starts: each parity holds every queue in table order,
 * a queue of path slots taking Q entries and the shadow queue Q * NL (k is a constant where the
 * kernels call this, so the sum folds). */
#define ST_X_QUEUE_BEFORE(stage, QUEUE, HOLDS, GATE) \
  if ((int)ST_Q_##QUEUE < k) off += ST_HOLDS_##HOLDS == ST_HOLDS_SLOTS ? Q : Q * NL;
/* Entries of one parity of every queue: Q per queue of path slots, Q * NL for the shadow queue. */
inline uint queue_parity_words(uint Q, uint NL) { return (uint)ST_Q_PATH_QUEUES * Q + Q * NL; }
inline uint queue_offset(uint Q, uint NL, uint parity, int k) {
  uint off = parity * queue_parity_words(Q, NL);
  ST_STAGES(ST_X_QUEUE_BEFORE)
  return off;
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

/* Per-pixel work (ST_FEATURE_PIXEL_WORK): after both parities of the queues, one counter per
 * window pixel of the density lookups and majorant (DDA) steps that its paths' tracking, their
 * shadow rays and their camera rays' alpha estimates took in this render: the cost of a pixel's
 * samples, for the trace of an adaptive render (docs/adaptive.md "Measured"). Counts only: no
 * image value reads it. */
inline uint pixel_work_offset(uint Q, uint NL) { return 2u * queue_parity_words(Q, NL); }

/* Adaptive sampling (ST_FEATURE_ADAPTIVE): after the queues (and the work counters, where they are
 * compiled in), the render's list of entries, two words each: a window pixel (row-major index in
 * the window) and the offset of the entry's first sample from the render's first sample. A batch
 * is whole samples of these entries, in list order; a pixel may have several entries, each its own
 * range of samples (adaptive.cpp renders a round's pixels of every length as one list). */
inline uint active_pixels_offset(__constant const st_scene* scene, uint Q, uint NL) {
  return pixel_work_offset(Q, NL) + (ST_HAS_PIXEL_WORK ? (uint)(scene->window_width * scene->window_height) : 0u);
}

inline void pixel_work_add(__constant const st_scene* scene, __global uint* queues, uint Q, uint NL, uint pixel,
                           uint work) {
  const uint w = (uint)scene->window_width;
  const uint cw = (uint)scene->camera.width;
  const uint x = pixel % cw - (uint)scene->pixel_x0, y = pixel / cw - (uint)scene->pixel_y0;
  if (work) atomic_add(&queues[pixel_work_offset(Q, NL) + y * w + x], work);
}

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
/* Entries per path slot and bounce: one per light, and with equi-angular sampling one more
 * (equiangular.h), whose ring-0 entry's Ls is its accumulator as a light's is. */
inline int shadow_lights(__constant const st_scene* scene) {
  return scene->n_lights + (ST_HAS_EQUIANGULAR && scene->equiangular.n_local > 0 ? 1 : 0);
}
inline int shadow_ring(uint NL, int n_lights) { return n_lights > 0 ? (int)(NL / (uint)n_lights) : 1; }
inline uint shadow_entry(uint slot, uint NL, int n_lights, int bounce, int light) {
  return slot * NL + (uint)(bounce % shadow_ring(NL, n_lights)) * (uint)n_lights + (uint)light;
}

/* The groups of a shadow entry's transmittance estimate (shadow_state.h): T, and ray marching's
 * other fields where the feature mask compiles ray marching in. */
#define ST_SHADOW_TRANS (ST_SHADOW_T | (ST_HAS_RAY_MARCHING ? ST_SHADOW_MARCH : 0))
/* What shadow_begin sets: an entry's ray, weight, estimate, stream and owner, and its state. */
#define ST_SHADOW_BEGUN (ST_SHADOW_RAY | ST_SHADOW_WEIGHT | ST_SHADOW_TRANS | ST_SHADOW_KEY | ST_SHADOW_STATUS)

/* Adds finished entry e, of bounce `bounce`, to its light's accumulator (the Ls of entry acc) and
 * empties it; the first scattering event's shadow rays also go to the direct pass (types.h
 * ST_AOVS) of the path's result `r` (its first float4 in the batch result buffer). A shadow
 * catcher's entry (ground.h) goes to the shadow layer only. Returns the entry's weight * T. */
inline float4 shadow_fold(__constant const st_scene* scene, ST_SHADOW_STATE shadows, uint n, uint acc, uint e,
                          int bounce, __global float4* r) {
  st_shadow s;
  shadow_load(shadows, n, e, ST_SHADOW_WEIGHT | ST_SHADOW_T, &s);
  const float4 c = s.weight * s.tr.T;
  s.state = ST_SHADOW_EMPTY;
  shadow_store(shadows, n, e, ST_SHADOW_STATUS, &s);
  if (ST_HAS_GROUND && s.catcher) {
    r[ST_RESULT_SHADOW] += c;
    return c;
  }
  st_shadow a;
  shadow_load(shadows, n, acc, ST_SHADOW_LS, &a);
  a.Ls += c;
  shadow_store(shadows, n, acc, ST_SHADOW_LS, &a);
  if (ST_HAS_AOV && scene->result_layers > ST_RESULT_LAYERS_AOV && bounce == 0) r[ST_RESULT_DIRECT] += c;
  return c;
}

/* A shadow entry's start (ST_SHADOW_BEGUN, stored by the caller): the ray from o along wi up to
 * t_max (a local light's distance, else INFINITY), its weight, an empty transmittance estimate of
 * the carried channels, its own random stream, its path's slot and whether it is the shadow
 * catcher's (ground.h). */
inline void shadow_begin(st_shadow* sh, float3 o, float3 wi, float t_max, float4 weight, float4 mask, uint stream,
                         uint slot, uint catcher) {
  sh->o = (float4)(o, 0.0f);
  sh->d = (float4)(wi, 0.0f);
  sh->t_max = t_max;
  sh->weight = weight;
  sh->catcher = catcher;
  transmittance_begin(&sh->tr, mask);
  sh->rng_draw = 0u;
  sh->stream = stream;
  sh->slot = slot;
  sh->state = ST_SHADOW_PENDING;
}

/* Spectral mode (st_film_color): the four wavelengths of sample (pixel, sample), shared by the
 * paths of a per-channel tracker's sample, so they depend only on the seed, pixel and sample.
 * raygen.cl draws them once into st_path.lambda. Independent (st_wavelength_sampling): the hero's
 * CDF value u is the first draw of a stream of its own (ST_STREAM_WAVELENGTHS on channel 0).
 * Stratified: u = r + j/16 (mod 1), r a hash (hash.h hash_uniform) of the seed, the pixel and the
 * sample's block of ST_WAVELENGTH_BLOCK samples of the sequence (with guiding, whose training
 * samples come first, the render's sample s is the sequence's s + wavelength_sample_offset, so
 * blocks stay aligned with adaptive sampling's rounds), j its place in the block bit-reversed
 * (0, 2, 1, 3), so that a whole block's 16 lanes are evenly spaced in the CDF and its first two
 * samples' 8 lanes too. Each sample's u is uniform because r is, so every sample is the same
 * estimate as an independent one; blocks are independent of one another. */
#if ST_WAVELENGTH_BLOCK != 4
#error "path_wavelengths reverses the 2 bits of a sample's place in its block"
#endif
inline float4 path_wavelengths(__constant const st_scene* scene, const st_path* p) {
  if (scene->wavelength_sampling == ST_WAVELENGTHS_STRATIFIED) {
    const uint s = p->sample + (uint)scene->wavelength_sample_offset;
    const uint j = s % ST_WAVELENGTH_BLOCK;
    const float r = hash_uniform(scene->seed ^ ST_STREAM_WAVELENGTHS, p->pixel, s / ST_WAVELENGTH_BLOCK);
    const float u = r + (float)(((j & 1u) << 1) | (j >> 1)) * (1.0f / (4.0f * ST_WAVELENGTH_BLOCK));
    return sample_wavelengths(fmin(u - floor(u), 0x1.fffffep-1f), 4);
  }
  st_rng r = rng_make(scene->seed, p->pixel, p->sample, 0u, ST_STREAM_WAVELENGTHS, 0u);
  return sample_wavelengths(rng_uniform(&r), 4);
}

/* The time of sample (pixel, sample) in the shutter, as a fraction u in [0, 1) of it (the time
 * is open + u (close - open), st_camera.shutter): the pixel's N samples (shutter.z) are
 * stratified, sample s in stratum s mod N with a uniform offset inside it, and the strata are
 * rotated by a uniform per pixel (Cranley-Patterson), so every sample's u is uniform on its own and
 * a pixel's N samples cover the shutter evenly. Both uniforms are hashes (hash.h hash_uniform) of
 * the seed, the stream ST_STREAM_TIME, the pixel and the sample (the rotation: of the pixel
 * alone), not Philox draws: every kernel that looks a moving medium up recomputes the time, and two
 * Philox calls per path and kernel cost several percent of a blurred render. The time depends
 * only on the seed, pixel and sample, so the paths of a per-channel tracker's sample share it and
 * shards merge exactly. */
inline float path_shutter_u(__constant const st_scene* scene, uint pixel, uint sample) {
  const uint N = (uint)scene->camera.shutter.z;
  const float xi = hash_uniform(scene->seed ^ ST_STREAM_TIME, pixel, sample);
  const float rotation = hash_uniform(scene->seed ^ 0x68E31DA4u, pixel, ST_STREAM_TIME);
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

/* The groups of the path state (path_state.h) that the tracking and shadow kernels read besides
 * their own, each only where the kernel's features read it: the wavelengths in spectral mode (rgb
 * mode reads none), what the path gathered where emission or a sphere light adds to it, and the
 * vertex (depth, result index) where the layers, a ground or a sphere light read it. */
#define ST_PATH_SPECTRUM_READ (ST_HAS_SPECTRAL ? ST_PATH_SPECTRUM : 0)
#define ST_PATH_TRACK_GATHERS (ST_HAS_EMISSION || ST_HAS_SPHERE_LIGHT ? ST_PATH_RADIANCE : 0)
#define ST_PATH_TRACK_READS                                                  \
  (ST_PATH_TRACK | ST_PATH_KEY | ST_PATH_SPECTRUM_READ | ST_PATH_TRACK_GATHERS | \
   (ST_HAS_AOV || ST_HAS_GROUND || ST_HAS_SPHERE_LIGHT ? ST_PATH_VERTEX : 0))
#define ST_PATH_SHADOW_READS (ST_PATH_KEY | ST_PATH_SPECTRUM_READ)

/* The random stream of a path (stream 0) or of one of its shadow rays. */
inline st_rng path_rng(__constant const st_scene* scene, const st_path* p, uint stream, uint draw) {
  st_rng r = rng_make(scene->seed, p->pixel, p->sample, p->channel, stream, draw);
  if (spectral_mode(scene)) r.lambda = p->lambda;
  if (ST_HAS_VELOCITY) r.time = path_time(scene, p->pixel, p->sample);
  return r;
}

#endif
