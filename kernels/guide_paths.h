/* guide_paths.h: what guiding does along a path on the device (docs/guiding.md): the radiance
 * records of training passes (a ring of the path's last scatter vertices, credited with every later
 * contribution) and guided Russian roulette and splitting in the render.
 *
 * Design: included by guiding.h on the device only, after the cache's structs and lookups (and,
 * in the program, after spectrum.h); each kernel calls these only where the feature mask has
 * ST_FEATURE_GUIDING (features.h). Every radiance the guide keeps (a record's weight, a vertex's
 * running total, a path's end, hence a region's radiance) is the mean over the path's lanes of
 * the radiance times guide_lane_weights: the film's unit, which the pixel estimates it is compared
 * with are in. */
#ifndef SPECTRACK_GUIDE_PATHS_H
#define SPECTRACK_GUIDE_PATHS_H

/* Appends one record (the count is the buffer's first uint; the records start 16 bytes in) with
 * `phase` in pos.w (the fit's records: f_phase at the direction; the host reads it, then bins the
 * records by position into its refined regions and writes their region there). The host drains
 * the buffer after every iteration, and its capacity is the shadow queue's, so no record is lost. */
inline void guide_record_push(__global uint* rec, uint capacity, float3 pos, float phase, float3 dir, float weight,
                              uint4 key) {
  uint i = atomic_inc(&rec[0]);
  if (i >= capacity) return;
  __global st_guide_record* r = (__global st_guide_record*)(rec + 4) + i;
  r->pos = (float4)(pos, phase);
  r->dir = (float4)(dir, weight);
  r->key[0] = key.x;
  r->key[1] = key.y;
  r->key[2] = key.z;
  r->key[3] = key.w;
}

/* The record buffer of a training pass: a uint count (16 bytes), `capacity` records, one
 * st_guide_slot per path slot (Q of them), then ST_GUIDE_RING vertices per path slot. Outside
 * training it holds the count only, and no kernel reads further. */
inline __global st_guide_slot* guide_slot(__global uint* rec, uint capacity, uint slot) {
  return (__global st_guide_slot*)(rec + 4 + capacity * (ST_SIZEOF_GUIDE_RECORD / 4)) + slot;
}
inline __global st_guide_vertex* guide_ring(__global uint* rec, uint capacity, uint Q, uint slot) {
  return (__global st_guide_vertex*)guide_slot(rec, capacity, Q) + slot * ST_GUIDE_RING;
}

/* Whether path p makes records: in a training pass (the header's inv_cell.w: the fraction of the
 * pass's camera samples that do), where its camera sample is one of them. */
inline int guide_training_path(__global const st_guide_header* h, const st_path* p) {
  return h->inv_cell.w > 0.0f && guide_sample_records(h->inv_cell.w, p->pixel, p->sample);
}

/* The weights that turn a path's radiance into the film's unit, lane by lane. In RGB mode a lane
 * is a channel of the film: 1. In spectral mode lane i is the radiance at wavelength lambda_i (an
 * upsampled light colour carries D65, about 100 at 560 nm), which film_rgb turns into linear sRGB
 * with F(lambda_i) / p(lambda_i): the weight is the mean of F's three channels over p, so that the
 * weighted lanes' mean is, in expectation over the wavelengths, the mean of R, G and B of the
 * radiance, the unit of the pixel estimates (guided roulette compares the two). */
inline float4 guide_lane_weights(__constant const st_scene* scene, const st_path* p) {
  if (!spectral_mode(scene)) return (float4)(1.0f);
  const float4 pdf = wavelength_pdfs(p->lambda);
  const float4 F[4] = {film_table_at(p->lambda.x), film_table_at(p->lambda.y), film_table_at(p->lambda.z),
                       film_table_at(p->lambda.w)};
  const float4 Fbar = (float4)(F[0].x + F[0].y + F[0].z, F[1].x + F[1].y + F[1].z, F[2].x + F[2].y + F[2].z,
                               F[3].x + F[3].y + F[3].z) * (1.0f / 3.0f);
  return select(Fbar / pdf, (float4)(0.0f), isequal(pdf, (float4)(0.0f)));
}

/* The guide's scalar of a radiance c of the path: the mean over its lanes of c in the film's unit. */
inline float guide_radiance(float4 c, float4 lw, float4 mask) { return masked_avg(c * lw, mask); }

/* The mean over the path's lanes of c / beta in the film's unit (lanes whose beta is 0 left out):
 * what a contribution c of the path says about the radiance at a vertex that beta arrived at. */
inline float guide_ratio(float4 c, float4 lw, float4 beta, float4 mask) {
  c *= lw;
  float cc[4] = {c.x, c.y, c.z, c.w}, bb[4] = {beta.x, beta.y, beta.z, beta.w}, mm[4] = {mask.x, mask.y, mask.z, mask.w};
  float sum = 0.0f, n = 0.0f;
  for (int i = 0; i < 4; ++i)
    if (mm[i] > 0.0f && bb[i] != 0.0f) sum += cc[i] / bb[i], n += 1.0f;
  return n > 0.0f ? sum / n : 0.0f;
}

/* Credits the contribution c to the ring's vertices of depths first .. last (those below 0 or out
 * of the ring are skipped); the ring's later vertices (depths last + 1 .. depth - 1) add it to
 * what their record's radiance leaves out (st_guide_vertex.total). */
inline void guide_credit(__global st_guide_vertex* ring, int first, int last, int depth, float4 c, float4 lw,
                         float4 mask) {
  if (!(masked_max(fabs(c), mask) > 0.0f)) return;
  for (int k = max(max(first, 0), depth - ST_GUIDE_RING); k < depth; ++k) {
    __global st_guide_vertex* v = &ring[k % ST_GUIDE_RING];
    if (k <= last) v->pos.w += guide_ratio(c, lw, v->beta, mask);
    else v->total.x += guide_radiance(c, lw, mask);
  }
}

/* Vertex `depth` of a training path enters the ring: its position, scattered direction wi with the
 * phase function's value f there, the throughput beta_in that arrived at it, and the path's
 * radiance so far (guide_radiance) `total`. A ground vertex (a surface outside every medium, which
 * is neither guided nor split) enters with f = ST_GUIDE_NO_RECORD: it keeps the ring's order but
 * makes no record (its records would fall outside the grid and be binned into the nearest cell). */
#define ST_GUIDE_NO_RECORD -1.0f
inline void guide_ring_enter(__global st_guide_vertex* ring, int depth, float3 x, float3 wi, float f, float4 beta_in,
                             float total) {
  __global st_guide_vertex* v = &ring[depth % ST_GUIDE_RING];
  v->pos = (float4)(x, 0.0f);
  v->dir = (float4)(wi, f);
  v->beta = beta_in;
  v->total = (float4)(total, 0.0f, 0.0f, 0.0f);
}


/* A training path's camera ray that ends on a shadow catcher (scatter.cl): the ground point is its
 * vertex 0, which makes no record, and what the path gathers from there is counted from now, so
 * that k_finish credits and records this path's ring, not what an earlier path left in the slot. */
inline void guide_training_catcher(__global const st_guide_header* h, __global uint* rec, uint Q, uint slot,
                                   const st_path* p) {
  guide_slot(rec, (uint)h->dims[3], slot)->L_seen = p->L;
  guide_ring_enter(guide_ring(rec, (uint)h->dims[3], Q, slot), p->depth, p->o.xyz, (float3)(0.0f), ST_GUIDE_NO_RECORD,
                   p->beta, 0.0f);
}

/* The record of ring vertex k of a path: what its scattered direction brought back per unit
 * throughput arriving at it, f_phase L / p_mix (its credited sum): the fit's density then follows
 * the product of the phase function and the incident radiance, averaged over the region's
 * vertices (at the first scatter event their propagation directions are close: the camera's).
 * With the phase product (guiding.h) the record is L / p_mix (the sum over f_phase): the fit
 * follows the incident radiance alone, and each event multiplies it with its own phase lobe. */
inline void guide_vertex_record(__global uint* rec, __global const st_guide_header* h, __global st_guide_vertex* v,
                                uint4 key, float4 mask) {
  if (v->dir.w == ST_GUIDE_NO_RECORD) return;
  const float to_L = h->phase_product ? (v->dir.w > 0.0f ? 1.0f / v->dir.w : 0.0f) : 1.0f;
  const float w = v->pos.w * to_L;
  /* only the guided scatter events fit; a weight of 0 too (the host may weigh it by the whole path) */
  if ((int)key.w < h->guided_depth && w >= 0.0f && isfinite(w))
    guide_record_push(rec, (uint)h->dims[3], v->pos.xyz, v->dir.w, v->dir.xyz, w, key);
  const float b = masked_avg(fabs(v->beta), mask);
  if (b > 0.0f && isfinite(v->total.x))
    guide_record_push(rec, (uint)h->dims[3], v->pos.xyz, 0.0f, (float3)(v->total.x, b, to_L), 0.0f,
                      (uint4)(key.xyz, key.w | ST_GUIDE_RECORD_RADIANCE));
}
/* A scatter event of a training path: credits what the path gathered since its last scatter
 * event (emission) to its vertices, records the vertex that leaves the ring; the slot's state
 * starts at the path's first scatter event. */
inline void guide_training_scatter(__global const st_guide_header* h, __global uint* rec, __global st_guide_vertex* ring,
                                   uint slot, const st_path* p, float4 lw, float4 mask) {
  __global st_guide_slot* gs = guide_slot(rec, (uint)h->dims[3], slot);
  if (p->depth == 0) gs->L_seen = p->L;
  guide_credit(ring, 0, p->depth - 1, p->depth, p->L - gs->L_seen, lw, mask);
  gs->L_seen = p->L;
  if (p->depth >= ST_GUIDE_RING) /* vertex depth - RING leaves the ring */
    guide_vertex_record(rec, h, &ring[p->depth % ST_GUIDE_RING],
                        (uint4)(p->pixel, p->sample, p->channel, (uint)(p->depth - ST_GUIDE_RING)), mask);
}

/* The radiance a path has gathered so far (guide_radiance): its L and its lights' accumulators
 * (the folded shadow rays). */
inline float guide_path_total(ST_SHADOW_STATE shadows, uint n, uint NL, int n_lights, uint slot, const st_path* p,
                              float4 lw, float4 mask) {
  return guide_radiance(shadow_gathered(shadows, n, NL, n_lights, slot, p->L), lw, mask);
}

/* A finished training path (its shadow rays folded): credits what it gathered since its last
 * scatter event, records the vertices left in its ring and appends its end record. */
inline void guide_training_finish(__global const st_guide_header* h, __global uint* rec, __global st_guide_vertex* ring,
                                  uint slot, const st_path* p, float4 lw, float4 mask, float total) {
  if (p->depth <= 0) return;
  guide_credit(ring, 0, p->depth - 1, p->depth, p->L - guide_slot(rec, (uint)h->dims[3], slot)->L_seen, lw, mask);
  for (int k = max(0, p->depth - ST_GUIDE_RING); k < p->depth; ++k)
    guide_vertex_record(rec, h, &ring[k % ST_GUIDE_RING], (uint4)(p->pixel, p->sample, p->channel, (uint)k), mask);
  guide_record_push(rec, (uint)h->dims[3], (float3)(0.0f), 0.0f, (float3)(total, 0.0f, 0.0f), 0.0f,
                    (uint4)(p->pixel, p->sample, p->channel, ST_GUIDE_RECORD_END));
}

/* ---- guided Russian roulette and splitting (Vorba and Krivanek 2016, docs/guiding.md) ----
 * After the regions the cache buffer holds the training passes' estimate of every film pixel (the
 * mean over its samples and RGB channels). At a scatter event whose direction is not drawn yet,
 * the ratio q of the path's expected contribution from there on (its throughput's lane mean times
 * the region's mean radiance per unit throughput) to its pixel's estimate decides: below
 * rr_below the path survives with probability max(q, rr_floor), its throughput divided by it;
 * from 1.5 on it splits into n = min(round(q), split_max) paths of throughput beta / n. Both keep
 * the expectation, for any cache. Splitting is depth first inside the path's slot: the parent goes
 * on as the first path and the n - 1 others wait in the slot's st_guide_slot; when a path of the
 * family finishes, the next waiting child restarts there (its parent's next-event estimation is
 * not repeated), with random streams of its own (its split id in the key). The family's radiance
 * carries over from path to path and the sample is written once, by its last path, so the image
 * does not depend on the schedule, the device or the shard. While a child waits, the family does
 * not split again (roulette still applies); a family starts at most ST_GUIDE_FAMILY_MAX children. */
#define ST_GUIDE_FAMILY_MAX 64u

inline __global const float* guide_pixel_estimates(__global const st_guide_header* h) {
  return (__global const float*)(guide_nodes(h) + h->nodes);
}

/* The slot's guide state where guided roulette and splitting are on (the render, not training). */
inline __global st_guide_slot* guide_split_slot(__global const st_guide_header* h, __global uint* rec, uint slot) {
  return ST_HAS_GUIDING && h->split_max > 0 ? guide_slot(rec, (uint)h->dims[3], slot) : 0;
}

/* The random key of the path in `slot`: its split id times an odd constant (a bijection of the
 * 32-bit ids) folded into the key's second word; id 0, the camera path, keeps the plain key. */
inline void guide_rng_key(st_rng* r, __global const st_guide_header* h, __global uint* rec, uint slot) {
  __global st_guide_slot* gs = guide_split_slot(h, rec, slot);
  if (gs) r->key.y ^= gs->split[0] * 0x9E3779B9u;
}

/* A new camera path in the slot: no family yet. */
inline void guide_split_begin(__global const st_guide_header* h, __global uint* rec, uint slot) {
  __global st_guide_slot* gs = guide_split_slot(h, rec, slot);
  if (gs)
    for (int k = 0; k < 4; ++k) gs->split[k] = 0u;
}

/* Guided roulette and splitting at the scatter event of *p (above): returns 0 when the path ends,
 * n >= 2 when it splits (beta divided by n, n - 1 children saved in the slot), 1 when it goes on,
 * and -1 where the region or the pixel has no estimate (the throughput's roulette applies). */
inline int guide_rrs(__global const st_guide_header* h, __global st_guide_slot* gs, st_path* p, float4 mask, st_rng* rng) {
  __global const st_guide_region* r = guide_regions(h) + guide_region_index(h, p->o.x, p->o.y, p->o.z);
  const float estimate = guide_pixel_estimates(h)[p->pixel];
  if (!(r->records > 0.0f) || !(estimate > 0.0f) || !(r->radiance >= 0.0f)) return -1;
  const float q = masked_avg(fabs(p->beta), mask) * r->radiance / estimate;
  if (!isfinite(q)) return -1; /* a path whose throughput is not finite (its sample is dropped): no splitting */
  if (q < h->rr_below) {
    const float survive = fmax(q, h->rr_floor);
    if (rng_uniform(rng) >= survive) return 0;
    p->beta /= survive;
    return 1;
  }
  const int n = min((int)fmin(q + 0.5f, 1e6f), h->split_max);
  if (n < 2 || gs->split[1] > 0u || gs->split[2] + (uint)n > ST_GUIDE_FAMILY_MAX) return 1;
  p->beta /= (float)n;
  gs->saved = *p;
  gs->split[1] = (uint)(n - 1);
  return n;
}

/* A finished path of a family with a waiting child: the child takes the slot (its saved state, the
 * family's radiance L so far, a new split id and stream) and resumes its parent's scatter event.
 * Returns 1 when a child restarted (the sample is not written yet). */
inline int guide_next_child(__global const st_guide_header* h, __global uint* rec, uint slot, st_path* p) {
  __global st_guide_slot* gs = guide_split_slot(h, rec, slot);
  if (!gs || gs->split[1] == 0u) return 0;
  const float4 L = p->L;
  *p = gs->saved;
  p->L = L;
  p->pending = 0;
  p->rng_draw = 0u;
  gs->split[1] -= 1u;
  gs->split[2] += 1u;
  gs->split[0] = gs->split[2];
  gs->split[3] = 1u;
  return 1;
}

#endif /* SPECTRACK_GUIDE_PATHS_H */
