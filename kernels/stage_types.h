/* stage_types.h: the wavefront's plain data shared by the host and the kernels: its stage table
 * and queues, the counters the device sums per iteration, and the arguments every stage kernel
 * takes. Part of
 * types.h (which includes it after ST_MAX_BATCHES_IN_FLIGHT); include types.h, not this file.
 */
#ifndef SPECTRACK_STAGE_TYPES_H
#define SPECTRACK_STAGE_TYPES_H

/* The wavefront's stages, in launch order: one row each, from which the queue enum, the host's
 * launch list, kernel warm-up, the queue buffer's layout and sizing and the queue trace all come
 * (src/integrator/stage_table.h). X(stage, QUEUE, HOLDS, GATE): the kernel k_<stage> (a wrapper
 * around stage_<stage>, kernels/stages.cl) reads queue ST_Q_<QUEUE>, whose items are path slots
 * (SLOTS: capacity Q) or shadow-ray entries (SHADOW: capacity Q * NL); GATE says when a render
 * launches it (ALWAYS; ESCAPE: the scene's escaping rays can see a light, ST_FEATURE_ESCAPE;
 * LIGHTS: the scene has shadow-ray entries, queues.h shadow_lights). Each stage reads the current
 * buffer of its queue and pushes into the next buffers (queues.h); FREE is one stack of free path
 * slots, not two buffers. Adding a stage is a row here and its stage function. */
#define ST_STAGES(X)                  \
  X(raygen, FREE, SLOTS, ALWAYS)      \
  X(track, TRACK, SLOTS, ALWAYS)      \
  X(escape, ESCAPE, SLOTS, ESCAPE)    \
  X(scatter, SCATTER, SLOTS, ALWAYS)  \
  X(shadow, SHADOW, SHADOW, LIGHTS)   \
  X(finish, FINISH, SLOTS, ALWAYS)
/* raygen: free path slots -> new camera paths; track: free-flight sampling; escape: paths that
 * left every medium see the lights at infinity; scatter: next-event estimation and phase sampling
 * at a real scattering event; shadow: transmittance of shadow rays; finish: a finished path
 * writes its sample once its shadow rays are done and frees its slot. */
enum st_queue_holds { ST_HOLDS_SLOTS = 0, ST_HOLDS_SHADOW = 1 };
enum st_stage_gate { ST_GATE_ALWAYS = 0, ST_GATE_ESCAPE = 1, ST_GATE_LIGHTS = 2 };
#define ST_X_QUEUE_ENUM(stage, QUEUE, HOLDS, GATE) ST_Q_##QUEUE,
#define ST_X_SLOT_QUEUE(stage, QUEUE, HOLDS, GATE) +(ST_HOLDS_##HOLDS == ST_HOLDS_SLOTS ? 1 : 0)
enum st_queue {
  ST_STAGES(ST_X_QUEUE_ENUM)
  ST_Q_COUNT,
  ST_Q_PATH_QUEUES = 0 ST_STAGES(ST_X_SLOT_QUEUE) /* queues of path slots */
};

/* Statistic counters that the device sums per iteration (32-bit) and k_advance adds into 64-bit
 * totals (wavefront.h st_loop.sums): X(ENUM suffix, RenderStats field, --stats-json key). The one
 * list behind the enum, the fold and the JSON names (Cycles' state_template.h pattern). */
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
  ST_C_TICKET,                               /* ST_Q_COUNT entries: items of each queue taken (ST_ITEMS_GRABBED) */
  ST_C_COUNT = ST_C_TICKET + ST_Q_COUNT
};

/* Arguments of every stage kernel after the scene (ST_ARG_SCENE = 0), in order: X(ENUM suffix,
 * OpenCL C type, name). The one list behind enum st_stage_arg, by which the host binds them, and
 * the kernels' and stage functions' parameter lists (kernels/queues.h), so an argument is one row.
 * The loop state's st_iteration changes every iteration (k_advance, wavefront.h); the guide cache
 * and the radiance records (kernels/guiding.h) are read only by kernels compiled with guiding. */
#define ST_STAGE_ARG_LIST(X)                                                          \
  X(GRIDS, __global const uint*, grids)                                               \
  X(MAJORANTS, __global const float2*, maj)                                           \
  X(ENV, __global const float*, env)                                                  \
  X(PATHS, ST_PATH_STATE, paths) /* path_state.h: AoS or SoA */                      \
  X(SHADOWS, ST_SHADOW_STATE, shadows) /* shadow_state.h: AoS or SoA */              \
  X(QUEUES, __global uint*, queues)                                                   \
  X(COUNTERS, __global uint*, counters)                                               \
  X(RESULTS, __global float4*, results)                                               \
  X(SLOTS, uint, Q)            /* path slots */                                       \
  X(LIGHTS, uint, NL)          /* shadow-ray entries per path slot (lights * ring) */ \
  X(LOOP, __global const st_loop*, loop) /* the loop state (wavefront.h): its `it` */ \
  X(GUIDE, __global const st_guide_header*, guide) /* st_guide_header, then its regions */ \
  X(GUIDE_RECORDS, __global uint*, guide_records) /* a uint count, then st_guide_record entries */
#define ST_X_ARG_ENUM(E, type, name) ST_ARG_##E,
enum st_stage_arg {
  ST_ARG_SCENE = 0, /* __constant const st_scene* scene */
  ST_STAGE_ARG_LIST(ST_X_ARG_ENUM)
  ST_ARG_COUNT
};

#endif /* SPECTRACK_STAGE_TYPES_H */
