/* queues.h: the wavefront's device queues and counters.
 * Every queue has two buffers (parity cur / 1 - cur); a stage reads n items of its queue in the
 * current buffer and pushes into the next buffers with atomic_inc on the next-size counters,
 * which the host reads once per iteration. Queues FREE..FINISH hold path slots (capacity Q);
 * SHADOW holds shadow-ray ids slot * NL + light (capacity Q * NL). */
#ifndef SPECTRACK_QUEUES_H
#define SPECTRACK_QUEUES_H

#define ST_STAGE_ARGS                                                                              \
  __constant const st_scene *scene, __global const uint *grids, __global const float2 *maj,       \
      __global const float *env, __global st_path *paths, __global st_shadow *shadows,            \
      __global uint *queues, __global uint *counters, __global float4 *results, uint Q, uint NL,   \
      uint cur, uint n

inline uint queue_offset(uint Q, uint NL, uint parity, int k) {
  return parity * (5u * Q + Q * NL) + (uint)k * Q;
}

inline void queue_push(__global uint* queues, __global uint* counters, uint Q, uint NL, uint cur, int k, uint item) {
  uint i = atomic_inc(&counters[ST_C_QUEUE + k]);
  queues[queue_offset(Q, NL, 1u - cur, k) + i] = item;
}

inline uint queue_item(__global const uint* queues, uint Q, uint NL, uint cur, int k, uint i) {
  return queues[queue_offset(Q, NL, cur, k) + i];
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

/* The random stream of a path (stream 0) or of one of its shadow rays. */
inline st_rng path_rng(__constant const st_scene* scene, const st_path* p, uint stream, uint draw) {
  return rng_make(scene->seed, p->pixel, p->sample, p->channel, stream, draw);
}

#endif
