/* stage_types.h: the wavefront's plain data shared by the host and the kernels: its queues, the
 * counters the device sums per iteration, and the arguments every stage kernel takes. Part of
 * types.h (which includes it after ST_MAX_BATCHES_IN_FLIGHT); include types.h, not this file.
 */
#ifndef SPECTRACK_STAGE_TYPES_H
#define SPECTRACK_STAGE_TYPES_H

/* Queues of the wavefront. Each stage reads the current buffer of its queue and pushes into the
 * next buffers; the host swaps them once per iteration. The queues before ST_Q_SHADOW hold path
 * slots (capacity Q each); ST_Q_SHADOW holds shadow-ray ids (capacity Q * lights). */
enum st_queue {
  ST_Q_FREE = 0,    /* free path slots (raygen input): one stack, not two buffers (queues.h free_push) */
  ST_Q_TRACK = 1,   /* paths to track (free-flight sampling) */
  ST_Q_ESCAPE = 2,  /* paths that left every medium (shade: environment and sun) */
  ST_Q_SCATTER = 3, /* paths at a real scattering event (NEE + phase sampling) */
  ST_Q_FINISH = 4,  /* finished paths (write the sample once its shadow rays are done) */
  ST_Q_SHADOW = 5,  /* shadow rays (transmittance); capacity slots * NL (lights * shadow ring) */
  ST_Q_COUNT = 6,
  ST_Q_PATH_QUEUES = ST_Q_SHADOW /* queues of path slots */
};

/* Statistic counters that the device sums per iteration (32-bit) and the host adds into 64-bit
 * totals: X(ENUM suffix, RenderStats field, --stats-json key). The one list behind the enum, the
 * host's fold and the JSON names (Cycles' state_template.h pattern). */
#define ST_SUM_COUNTERS(X)                                         \
  X(LOOKUPS_TRACK, lookups_track, "density_lookups_tracking")      \
  X(LOOKUPS_SHADOW, lookups_shadow, "density_lookups_shadow")      \
  X(LOOKUPS_EMISSION, lookups_emission, "emission_lookups")        \
  X(LOOKUPS_ALPHA, lookups_alpha, "density_lookups_alpha")         \
  X(REAL_COLLISIONS, real_collisions, "real_collisions")           \
  X(NULL_COLLISIONS, null_collisions, "null_collisions")           \
  X(CONTROL_COLLISIONS, control_collisions, "control_collisions")  \
  X(RESIDUAL_COLLISIONS, residual_collisions, "residual_collisions") \
  X(SCATTER_EVENTS, scatter_events, "scatter_events")              \
  X(DDA_STEPS, dda_steps, "dda_steps")                             \
  X(DDA_NONEMPTY, dda_nonempty, "dda_steps_nonempty")              \
  X(REQUEUES, requeues, "requeues")                                \
  X(WAITS, waits, "waiting_requeues")                              \
  X(NONFINITE, nonfinite_samples, "nonfinite_samples")             \
  X(SPLIT_PATHS, split_paths, "guide_split_paths")
#define ST_X_COUNTER_ENUM(E, field, key) ST_C_##E,
/* The counter buffer: queue sizes, finished paths per batch ring slot, the sums, the maximum. */
enum st_counter {
  ST_C_QUEUE = 0,                            /* ST_Q_COUNT entries: sizes of the next queues */
  ST_C_BATCH_DONE = ST_C_QUEUE + ST_Q_COUNT, /* ST_MAX_BATCHES_IN_FLIGHT entries: finished paths per ring slot */
  ST_C_SUMS_ANCHOR = ST_C_BATCH_DONE + ST_MAX_BATCHES_IN_FLIGHT - 1, /* the sums follow */
  ST_SUM_COUNTERS(ST_X_COUNTER_ENUM)
  ST_C_MAX_THROUGHPUT_BITS,                  /* float bits of the largest beta component (atomic_max) */
  ST_C_COUNT
};

/* Arguments of every stage kernel, in order (kernels/queues.h ST_STAGE_ARGS spells the same list;
 * the host binds by these names). st_iteration changes every iteration; the guide cache and the
 * radiance records (kernels/guiding.h) are read only by kernels compiled with guiding. */
enum st_stage_arg {
  ST_ARG_SCENE = 0,
  ST_ARG_GRIDS,
  ST_ARG_MAJORANTS,
  ST_ARG_ENV,
  ST_ARG_PATHS,
  ST_ARG_SHADOWS,
  ST_ARG_QUEUES,
  ST_ARG_COUNTERS,
  ST_ARG_RESULTS,
  ST_ARG_SLOTS,      /* Q: path slots */
  ST_ARG_LIGHTS,     /* NL: shadow-ray entries per path slot (lights * shadow ring) */
  ST_ARG_ITERATION,  /* st_iteration */
  ST_ARG_GUIDE,      /* the guide cache: st_guide_header, then its regions */
  ST_ARG_GUIDE_RECORDS, /* radiance records: a uint count, then st_guide_record entries */
  ST_ARG_COUNT
};

#endif /* SPECTRACK_STAGE_TYPES_H */
