/* stages.cl: the stage kernels, one per row of ST_STAGES (stage_types.h), each a short wrapper
 * around its stage function, and k_advance, which ends every iteration on the device (wavefront.h).
 * A stage kernel reads `it` from the loop state and runs its stage function on every item of its
 * queue, work-item i taking items i, i + G, i + 2G, ... (G the launch's work-items), or on a CPU
 * device runs in queue order (ST_FOR_QUEUE_ITEMS, wavefront.h): the host launches
 * every stage over a fixed number of work-items (at most the queue's capacity) without knowing
 * the queue's size. */
#include "types.h"
#include "queues.h"
#include "wavefront.h"

#define ST_X_STAGE_KERNEL(stage, QUEUE, HOLDS, GATE)                                          \
  __kernel void k_##stage(ST_STAGE_ARGS) {                                                    \
    const st_iteration it = loop->it;                                                         \
    const uint n = stage_items(&it, ST_Q_##QUEUE);                                            \
    ST_FOR_QUEUE_ITEMS(i, n, &counters[ST_C_TICKET + ST_Q_##QUEUE])                          \
      stage_##stage(ST_STAGE_PASS(it, i));                                                    \
  }
ST_STAGES(ST_X_STAGE_KERNEL)

/* Folds the counters of the iteration that ran into the loop state, and clears them. */
inline void loop_fold(st_loop* s, __global uint* counters) {
  uint slots = 0u, busy = 0u;
  for (int q = 0; q < ST_Q_COUNT; ++q) {
    s->n_q[q] = counters[ST_C_QUEUE + q];
    if (q == ST_Q_FREE) s->n_q[q] += s->free_kept; /* the stack: kept + pushed by finish */
    if (ST_SLOT_QUEUE_BITS & (1u << q)) slots += s->n_q[q];
    if ((ST_SLOT_QUEUE_BITS & (1u << q)) && q != ST_Q_FREE) busy += s->n_q[q];
  }
  /* every path slot is in exactly one queue of path slots at an iteration boundary */
  if (slots != s->Q) s->status = ST_LOOP_SLOTS_LOST;
  s->busy_sum += busy;
  s->busy_min = s->iterations == 0u ? busy : min(s->busy_min, busy);
  if (2u * busy < s->Q) s->below_half++;
  s->iterations++;
  s->cur = 1u - s->cur;
  for (uint r = 0; r < s->ring; ++r) s->batch_done[r] += counters[ST_C_BATCH_DONE + r];
  for (int k = 0; k < ST_SUM_COUNT; ++k) s->sums[k] += counters[ST_C_SUMS_ANCHOR + 1 + k];
  s->max_bits = max(s->max_bits, counters[ST_C_MAX_THROUGHPUT_BITS]);
  for (int c = 0; c < ST_C_COUNT; ++c) counters[c] = 0u;
  s->live = 0u;
}

/* Marks every completed batch, in batch order, for the next k_accumulate. */
inline void loop_accumulate(st_loop* s) {
  s->acc_first = s->accumulated;
  while (s->accumulated < s->batches_target) {
    const uint b = s->accumulated, n = loop_batch_samples(s, b);
    const uint expected = n * s->paths_per_sample;
    if (s->batch_done[b % s->ring] < expected) break;
    s->batch_done[b % s->ring] -= expected;
    s->samples_done += n;
    s->accumulated++;
  }
  s->acc_end = s->accumulated;
}

/* The next iteration: the new paths (the first batch alone until it is on the film, so the first
 * pass is early; then the whole ring), or none when the loop is done, waits or failed. */
inline void loop_begin(st_loop* s) {
  for (int q = 0; q < ST_Q_COUNT; ++q) s->it.n_queue[q] = 0u;
  s->it.n_new = 0u;
  if (s->status != ST_LOOP_RUNNING && s->status != ST_LOOP_WAITING) return;
  if (s->accumulated >= s->batches_target) {
    s->status = ST_LOOP_DONE;
    return;
  }
  const ulong ahead = s->accumulated == 0u ? 1u : s->ring;
  const ulong issuable = (ulong)min(s->batches_target, s->batches_issuable);
  const ulong limit = min(min(s->total_paths, ((ulong)s->accumulated + ahead) * s->batch_paths), issuable * s->batch_paths);
  const uint n_new = (uint)min((ulong)s->n_q[ST_Q_FREE], limit > s->issued ? limit - s->issued : 0ul);
  uint in_flight = 0u;
  for (int q = 0; q < ST_Q_COUNT; ++q)
    if (q != ST_Q_FREE) in_flight += s->n_q[q];
  if (n_new == 0u && in_flight == 0u) {
    s->status = s->batches_issuable < s->batches_target && issuable * s->batch_paths <= s->issued ? ST_LOOP_WAITING
                                                                                                   : ST_LOOP_STALLED;
    return;
  }
  s->status = ST_LOOP_RUNNING;
  s->it.first = s->issued;
  s->it.cur = s->cur;
  for (int q = 0; q < ST_Q_COUNT; ++q) s->it.n_queue[q] = s->n_q[q];
  s->it.n_new = n_new;
  s->free_kept = s->n_q[ST_Q_FREE] - n_new;
  s->issued += n_new;
  s->live = 1u;
}

/* Ends an iteration (and, on a new loop state, starts the first): one work-item. */
__kernel void k_advance(__global st_loop* loop, __global uint* counters, uint host_sizeof_loop) {
  if (get_global_id(0) != 0u) return;
  st_loop s = *loop;
  if (host_sizeof_loop != (uint)sizeof(st_loop)) {
    loop->status = ST_LOOP_LAYOUT;
    loop->it.n_new = 0u;
    for (int q = 0; q < ST_Q_COUNT; ++q) loop->it.n_queue[q] = 0u;
    return;
  }
  if (s.live) loop_fold(&s, counters);
  loop_accumulate(&s);
  loop_begin(&s);
  *loop = s;
}
