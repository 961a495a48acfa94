/* track.cl: one call of the tracking routine per queued path; pushes the path to exactly one of
 * scatter (real scattering), escape (left every medium), finish (absorbed) or track again
 * (launch budget spent: it resumes at its saved t). */
#include "types.h"
#include "features.h"
#include "rng.h"
#include "spectrum.h"
#include "tracking.h"
#include "queues.h"

__kernel void k_track(ST_STAGE_ARGS) {
  const uint cur = it.cur, n = it.n_queue[ST_Q_TRACK];
  uint gid = get_global_id(0);
  if (gid >= n) return;
  uint slot = queue_item(queues, Q, NL, cur, ST_Q_TRACK, gid);
  st_path p = paths[slot];
  st_rng rng = path_rng(scene, &p, 0u, p.rng_draw);
  if (ST_HAS_GUIDING) guide_rng_key(&rng, guide, guide_records, slot); /* a split path's streams */
  st_track_stats st;
  track_stats_clear(&st);
  float t = p.o.w;
  int medium = 0;
  float4 beta = p.beta, L = p.L;
  float4 r_u = p.r_u;
  if (!spectral_mode(scene)) r_u.w = 0.0f; /* an unused lane: whatever the last launch left there */
  int ev = track_path(scene, grids, maj, p.o.xyz, p.d.xyz, &t, &beta, &r_u, (int)p.channel, path_mask(scene, &p), &L,
                      &medium, &rng, scene->iteration_budget, &st);
  p.r_u = r_u;
  p.beta = beta;
  /* the emission pass: what the camera segment (before any scattering) scored */
  if (ST_HAS_AOV && ST_HAS_EMISSION && scene->result_layers > ST_RESULT_LAYERS_AOV && p.depth == 0)
    results[p.result_index * (uint)scene->result_layers + ST_RESULT_EMISSION] += L - p.L;
  p.L = L;
  p.rng_draw = rng_draw_index(&rng);
  int q;
  if (ev == ST_EV_SCATTER) {
    p.o = (float4)(p.o.xyz + t * p.d.xyz, 0.0f);
    p.medium = medium;
    q = ST_Q_SCATTER;
  } else if (ev == ST_EV_ESCAPE) {
    /* no light is visible to an escaping ray: the escape stage would add exactly nothing */
    q = ST_HAS_ESCAPE ? ST_Q_ESCAPE : ST_Q_FINISH;
  } else if (ev == ST_EV_ABSORB) {
    q = ST_Q_FINISH;
  } else {
    p.o.w = t;
    q = ST_Q_TRACK;
    atomic_inc(&counters[ST_C_REQUEUES]);
  }
  paths[slot] = p;
  flush_track_stats(counters, &st, ST_C_LOOKUPS_TRACK);
  queue_push(queues, counters, Q, NL, cur, q, slot);
}
