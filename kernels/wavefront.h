/* wavefront.h: the stage loop's state on the device (st_loop), shared by the host and the kernels.
 *
 * Design: the queue sizes, the batches' progress and the statistics live on the device, so the
 * host never waits for them between iterations. An iteration is the stage launches (each stage
 * reads its queue's size from `it`), then k_advance (one work-item, kernels/stages.cl), which folds
 * the iteration's counters into this state (queue sizes, finished paths per batch ring slot,
 * 64-bit sums, occupancy), marks the completed batches for k_accumulate (launched next, it adds
 * them to the film in batch order), and writes the next iteration's `it`: the paths raygen issues
 * (from the top of the free stack, within the batches the ring and the host allow) and the queue
 * parity. The host writes the plan once, enqueues several iterations at a time and reads this state
 * every few iterations (src/integrator/stage_loop.cpp), for progress, the end, and its statistics.
 * Which slot a path occupies and when an iteration runs never change a result: paths are keyed
 * by (pixel, sample, channel), write their sample at their own result index, and the film adds
 * whole batches in batch order. Layout: the 64-bit fields first, then the 32-bit ones, the same on
 * the host and the device (k_advance compares sizeof with the host's and stops on a mismatch). */
#ifndef SPECTRACK_WAVEFRONT_H
#define SPECTRACK_WAVEFRONT_H

#include "types.h"

/* What the loop is doing after a k_advance. */
enum st_loop_status {
  ST_LOOP_RUNNING = 0,   /* `it` has work */
  ST_LOOP_DONE = 1,      /* every batch is on the film */
  ST_LOOP_WAITING = 2,   /* nothing in flight and the host's batches_issuable reached: the host's turn */
  ST_LOOP_STALLED = 3,   /* nothing in flight and nothing to issue (an internal error) */
  ST_LOOP_SLOTS_LOST = 4, /* the path queues do not hold every slot (an internal error) */
  ST_LOOP_LAYOUT = 5     /* the host's st_loop differs from the device's */
};

#define ST_X_SUM_ONE(E, field, key) +1
enum { ST_SUM_COUNT = 0 ST_SUM_COUNTERS(ST_X_SUM_ONE) };

typedef struct {
  st_iteration it;              /* what the next stage launches read */
  st_ulong issued;              /* paths issued so far */
  st_ulong total_paths;         /* of the render */
  st_ulong busy_sum;            /* path slots in flight at the iteration boundaries, summed */
  st_ulong sums[ST_SUM_COUNT];  /* ST_SUM_COUNTERS, in order */
  /* the plan (the host, once) */
  st_uint Q, ring, batch_paths, samples_per_batch, spp, paths_per_sample, batches_target;
  st_uint batches_issuable;     /* the host: batches that may be issued before it looks again */
  /* the loop */
  st_uint n_q[ST_Q_COUNT];      /* queue sizes at the iteration boundary (FREE: the free stack) */
  st_uint free_kept;            /* free slots raygen leaves below its places this iteration */
  st_uint cur;                  /* parity of the queue buffers the next iteration reads */
  st_uint live;                 /* `it` has work: the next k_advance folds its counters */
  st_uint status;               /* st_loop_status */
  st_uint accumulated;          /* batches on the film (or marked for the k_accumulate after this k_advance) */
  st_uint samples_done;         /* their samples */
  st_uint acc_first, acc_end;   /* batches the next k_accumulate adds */
  st_uint batch_done[ST_MAX_BATCHES_IN_FLIGHT]; /* finished paths per ring slot, not yet accumulated */
  st_uint iterations;           /* iterations with work */
  st_uint busy_min, below_half; /* occupancy: fewest busy slots; iterations with fewer than Q / 2 */
  st_uint max_bits;             /* float bits of the largest throughput component */
} st_loop;

/* Bit q is set for the queues of path slots. */
#define ST_X_SLOT_BIT(stage, QUEUE, HOLDS, GATE) | (ST_HOLDS_##HOLDS == ST_HOLDS_SLOTS ? 1u << ST_Q_##QUEUE : 0u)
enum { ST_SLOT_QUEUE_BITS = 0u ST_STAGES(ST_X_SLOT_BIT) };

/* Items of queue k in iteration `it`: raygen's are the n_new slots it fills. */
inline st_uint stage_items(const st_iteration* it, int k) {
  return k == ST_Q_FREE ? it->n_new : it->n_queue[k];
}

/* The items a work-item of a launch over a fixed number G of work-items takes, of n: every G-th
 * from its id (a GPU: neighbouring work-items read neighbouring entries), or with ST_ITEMS_BLOCKED
 * (a CPU device, src/integrator/loop_policy.h) a run of ceil(n / G) in order, so that a work-group,
 * whose work-items PoCL runs one after another, goes through its part of the queue in queue order. */
#if ST_ITEMS_BLOCKED
#define ST_FOR_ITEMS(i, n)                                                                          \
  for (uint st_per_ = (n) / (uint)get_global_size(0) + ((n) % (uint)get_global_size(0) != 0u),     \
            i = (uint)get_global_id(0) * st_per_, st_end_ = min((uint)(n), i + st_per_);           \
       i < st_end_; ++i)
#else
#define ST_FOR_ITEMS(i, n) for (uint i = (uint)get_global_id(0); i < (n); i += (uint)get_global_size(0))
#endif

/* The items of a stage's queue, of n, that a work-item takes. With ST_ITEMS_GRABBED
 * (SPECTRACK_ITEM_ORDER=grabbed, src/integrator/loop_policy.h) the launch's work-items take runs in queue
 * order from the queue's ticket counter as long as any are left, each run a 1 / (2 G) share of the
 * items not yet taken (G the launch's work-groups; guided self-scheduling: large runs first, single
 * items last): a launch has two work-groups per core, and a fixed share each would leave a core
 * idle while the other finishes its share of slower paths. The ticket is a counter (stage_types.h
 * ST_C_TICKET), cleared with the others when k_advance folds a live iteration; nothing takes a
 * ticket when n is 0, so an iteration without work leaves it at 0. Else ST_FOR_ITEMS. */
#if ST_ITEMS_GRABBED
inline uint items_grab(volatile __global uint* ticket, uint n, uint* run) {
  if (n == 0u) return 0u;
  const uint taken = *ticket; /* a guess: the atomic add decides */
  *run = max(1u, (n - min(n, taken)) / (2u * (uint)get_num_groups(0)));
  return atomic_add(ticket, *run);
}
#define ST_FOR_QUEUE_ITEMS(i, n, ticket)                                                           \
  for (uint st_n_ = (n), st_run_ = 0u, st_b_ = items_grab(ticket, st_n_, &st_run_); st_b_ < st_n_; \
       st_b_ = items_grab(ticket, st_n_, &st_run_))                                                \
    for (uint i = st_b_, st_e_ = min(st_n_, st_b_ + st_run_); i < st_e_; ++i)
#else
#define ST_FOR_QUEUE_ITEMS(i, n, ticket) ST_FOR_ITEMS(i, n)
#endif

/* Samples per pixel of batch b (the last batch may be shorter). */
inline st_uint loop_batch_samples(const st_loop* s, st_uint b) {
  const st_uint rest = s->spp - b * s->samples_per_batch;
  return s->samples_per_batch < rest ? s->samples_per_batch : rest;
}

#endif /* SPECTRACK_WAVEFRONT_H */
