/* finish.cl: a finished path (and all its shadow rays) writes its sample to the batch result
 * buffer at its own index; k_accumulate then adds a whole batch to the film per pixel in a fixed
 * order, so the image does not depend on the order in which paths finished (bit-identical
 * renders for one seed). Non-finite samples are counted and dropped, never hidden. */
__kernel void k_finish(ST_STAGE_ARGS) {
  const uint cur = it.cur, n = it.n_queue[ST_Q_FINISH];
  uint gid = get_global_id(0);
  if (gid >= n) return;
  uint slot = queue_item(queues, Q, NL, cur, ST_Q_FINISH, gid);
  st_path p = paths[slot];
  if (p.pending > 0) {
    atomic_inc(&counters[ST_C_WAITS]);
    queue_push(queues, counters, Q, NL, cur, ST_Q_FINISH, slot);
    return;
  }
  /* the shadow rays not added yet: bounces depth - R .. depth - 1 (R: the shadow ring), oldest first */
  for (int k = shadow_ring(NL, scene->n_lights); k >= 1; --k) {
    int bounce = p.depth - k;
    if (bounce < 0) continue;
    for (int l = 0; l < scene->n_lights; ++l) {
      __global st_shadow* e = &shadows[shadow_entry(slot, NL, scene->n_lights, bounce, l)];
      if (e->state == ST_SHADOW_DONE) shadow_fold(&shadows[slot * NL + (uint)l], e);
    }
  }
  float4 r = p.L;
  for (uint l = 0; l < (uint)scene->n_lights; ++l) r += shadows[slot * NL + l].Ls;
  r.w = 0.0f;
  if (!(isfinite(r.x) && isfinite(r.y) && isfinite(r.z))) {
    atomic_inc(&counters[ST_C_NONFINITE]);
    r = (float4)(0.0f);
  }
  results[p.result_index] = r;
  atomic_inc(&counters[ST_C_BATCH_DONE + p.batch]);
  free_push(queues, counters, Q, free_base(it.n_queue[ST_Q_FREE], it.n_new), slot);
}

/* Adds the n_samples samples (times channels) of each window pixel of one batch to the film.
 * film[pix] is the running sum and film[npix + pix] its Kahan compensation, so a pixel's sum is
 * exact to a few float roundings of its terms whatever the sample count: sample-range shards
 * merged on the host (in double) then agree with one long render to float precision. */
__kernel void k_accumulate(__global const float4* results, __global float4* film, uint base, uint n_samples,
                           uint npix, uint nch) {
  uint pix = get_global_id(0);
  if (pix >= npix) return;
  /* one sample at a time, in sample order: the sum does not depend on how samples were batched */
  float4 f = film[pix];
  float4 c = film[npix + pix];
  for (uint s = 0; s < n_samples; ++s)
    for (uint k = 0; k < nch; ++k) {
      float4 y = results[base + (s * npix + pix) * nch + k] - c;
      float4 t = f + y;
      c = (t - f) - y;
      f = t;
    }
  film[pix] = f;
  film[npix + pix] = c;
}
