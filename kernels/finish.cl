/* finish.cl: a finished path (and all its shadow rays) writes its sample to the batch result
 * buffer at its own index (in spectral mode its beauty and layers turned into linear sRGB); k_accumulate then adds a whole batch to the film per pixel in a fixed
 * order, so the image does not depend on the order in which paths finished (bit-identical
 * renders for one seed). Non-finite samples are counted and dropped, never hidden. */
#include "types.h"
#include "features.h"
#include "spectrum.h"
#include "queues.h"
#include "wavefront.h"
#include "equiangular.h"

/* Spectral mode: the radiance layers a path wrote at its wavelengths (environment, emission and
 * direct passes) become linear sRGB through the film, as its beauty does. Alpha (1 - T) and the
 * albedo (sigma_s / sigma_t) are linear sRGB already: raygen.cl turns them into reflectances under
 * D65 where it computes them (the film of D65 times them, so that a gray value stays itself and a
 * slab's alpha is 1 minus what a white sky shows through it), which frees their w lanes for the
 * first collision's weight and depth. */
inline void spectral_layers_to_rgb(__global float4* out, uint L, float4 lambda, float4 pdf) {
  out[ST_RESULT_ENVIRONMENT] = film_rgb(out[ST_RESULT_ENVIRONMENT], lambda, pdf, 4);
  if (L > ST_RESULT_LAYERS_AOV) {
    out[ST_RESULT_EMISSION] = film_rgb(out[ST_RESULT_EMISSION], lambda, pdf, 4);
    out[ST_RESULT_DIRECT] = film_rgb(out[ST_RESULT_DIRECT], lambda, pdf, 4);
  }
  if (ST_HAS_GROUND && L > ST_RESULT_UNSHADOWED) { /* the shadow catcher's irradiance estimates */
    out[ST_RESULT_SHADOW] = film_rgb(out[ST_RESULT_SHADOW], lambda, pdf, 4);
    out[ST_RESULT_UNSHADOWED] = film_rgb(out[ST_RESULT_UNSHADOWED], lambda, pdf, 4);
  }
}

ST_STAGE_FUNCTION(finish) {
  const uint cur = it.cur;
  uint slot = queue_item(queues, Q, NL, cur, ST_Q_FINISH, gid);
  st_path p;
  path_load(paths, Q, slot, ST_PATH_ALL, &p);
  if (p.pending > 0) {
    atomic_inc(&counters[ST_C_WAITS]);
    queue_push(queues, counters, Q, NL, cur, ST_Q_FINISH, slot);
    return;
  }
  /* the shadow rays not added yet: bounces depth - R .. depth - 1 (R: the shadow ring), oldest first;
   * a guide training pass credits them, and what the path gathered since its last scatter event,
   * to the path's vertices, which then become records (guiding.h) */
  const int training = ST_HAS_GUIDING && guide_training_path(guide, &p);
  __global st_guide_vertex* ring = training ? guide_ring(guide_records, (uint)guide->dims[3], Q, slot) : 0;
  const float4 mask = path_mask(scene, &p);
  const float4 lw = training ? guide_lane_weights(scene, &p) : (float4)(1.0f);
  const uint n = Q * NL;
  for (int k = shadow_ring(NL, shadow_lights(scene)); k >= 1; --k) {
    int bounce = p.depth - k;
    if (ea_on(scene)) ea_fold(scene, shadows, results, Q, NL, slot, &p, bounce + 1); /* the segment after it */
    if (bounce < 0) continue;
    for (int l = 0; l < scene->n_lights; ++l) {
      const uint e = shadow_entry(slot, NL, shadow_lights(scene), bounce, l);
      if (shadow_status(shadows, n, e) != ST_SHADOW_DONE) continue;
      const float4 c = shadow_fold(scene, shadows, n, slot * NL + (uint)l, e, bounce,
                                   &results[p.result_index * (uint)scene->result_layers]);
      if (training) guide_credit(ring, 0, bounce - 1, p.depth, c, lw, mask);
    }
  }
  if (training)
    guide_training_finish(guide, guide_records, ring, slot, &p, lw, mask,
                          guide_path_total(shadows, n, NL, shadow_lights(scene), slot, &p, lw, mask));
  /* splitting: a waiting child of the family takes the slot; the last path writes the sample */
  if (ST_HAS_GUIDING && guide_next_child(guide, guide_records, slot, &p)) {
    atomic_inc(&counters[ST_C_SPLIT_PATHS]);
    path_store(paths, Q, slot, ST_PATH_ALL, &p);
    queue_push(queues, counters, Q, NL, cur, ST_Q_SCATTER, slot);
    return;
  }
  float4 r = shadow_gathered(shadows, n, NL, shadow_lights(scene), slot, p.L);
  const uint L = (uint)scene->result_layers;
  __global float4* out = &results[p.result_index * L];
  if (spectral_mode(scene)) { /* the radiance at the path's four wavelengths becomes linear sRGB (w = 0) */
    const float4 lambda = p.lambda, pdf = wavelength_pdfs(lambda);
    r = film_rgb(r, lambda, pdf, 4);
    if (ST_HAS_AOV && L > 1u) spectral_layers_to_rgb(out, L, lambda, pdf);
  } else {
    r.w = 0.0f;
  }
  int finite = isfinite(r.x) && isfinite(r.y) && isfinite(r.z);
  if (ST_HAS_AOV && L > 1u) /* the layers the path wrote: a non-finite one drops all of this path's values
                             * (delta-per-channel: one of a sample's paths, as for the beauty) */
    for (uint k = 1u; k < L; ++k) finite = finite && isfinite(out[k].x) && isfinite(out[k].y) && isfinite(out[k].z);
  if (!finite) {
    atomic_inc(&counters[ST_C_NONFINITE]);
    r = (float4)(0.0f);
    if (ST_HAS_AOV)
      for (uint k = 1u; k < L; ++k) out[k] = (float4)(0.0f);
  }
  out[ST_RESULT_BEAUTY] = r;
  atomic_inc(&counters[ST_C_BATCH_DONE + p.result_index / it.batch_paths]); /* its batch's ring slot (raygen.cl) */
  free_push(queues, counters, Q, free_base(it.n_queue[ST_Q_FREE], it.n_new), slot);
}

/* Compensated (Kahan) addition of y to the sum *f with compensation *c. */
inline void kahan_add(float4* f, float4* c, float4 y) {
  float4 v = y - *c;
  float4 t = *f + v;
  *c = (t - *f) - v;
  *f = t;
}

/* Adds the batches the loop state marks (acc_first .. acc_end - 1, wavefront.h), in batch order,
 * each with its n_samples samples (times channels) of each window pixel, to the film.
 * The film holds `layers` float4 sums per pixel, layer l at film[2 * l * npix + pix] with its
 * Kahan compensation at film[(2 * l + 1) * npix + pix], so a pixel's sum is exact to a few float
 * roundings of its terms whatever the sample count: sample-range shards merged on the host (in
 * double) then agree with one long render to float precision. Layers 0 .. L - 1 are the batch
 * results' layers (st_result_layer); with `moments`, layer L sums the square of each sample's
 * whole beauty (the beauty and environment layers, over its channels' paths): the variance layer.
 * A work-item adds the pixels ST_FOR_ITEMS gives it (wavefront.h: every G-th, or a run). */
__kernel void k_accumulate(__global const float4* results, __global float4* film, __global const st_loop* loop,
                           uint npix, uint nch, uint L, uint moments) {
  const uint first = loop->acc_first, end = loop->acc_end;
  if (first == end) return;
  const st_loop s = *loop;
  ST_FOR_ITEMS(pix, npix) {
    /* one sample at a time, in sample order: the sum does not depend on how samples were batched */
    for (uint l = 0; l < L + moments; ++l) {
      float4 f = film[2u * l * npix + pix];
      float4 c = film[(2u * l + 1u) * npix + pix];
      for (uint b = first; b < end; ++b) {
        const uint base = (b % s.ring) * s.batch_paths, n_samples = loop_batch_samples(&s, b);
        for (uint sa = 0; sa < n_samples; ++sa) {
          if (l < L) {
            for (uint k = 0; k < nch; ++k) kahan_add(&f, &c, results[(base + (sa * npix + pix) * nch + k) * L + l]);
          } else {
            float4 x = (float4)(0.0f);
            for (uint k = 0; k < nch; ++k) {
              uint i = (base + (sa * npix + pix) * nch + k) * L;
              x += results[i + ST_RESULT_BEAUTY];
              if (L > 1u) x += results[i + ST_RESULT_ENVIRONMENT];
            }
            kahan_add(&f, &c, x * x);
          }
        }
      }
      film[2u * l * npix + pix] = f;
      film[(2u * l + 1u) * npix + pix] = c;
    }
  }
}
