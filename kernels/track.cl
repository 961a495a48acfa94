/* track.cl: one call of the tracking routine per queued path; pushes the path to exactly one of
 * scatter (real scattering, or a surface vertex at the ground), escape (left every medium), finish
 * (absorbed, or ended at the ground or a sphere light) or track again (launch budget spent: it
 * resumes at its saved t). The walk ends at the nearest surface (ground.h). */
#include "types.h"
#include "features.h"
#include "rng.h"
#include "spectrum.h"
#include "tracking.h"
#include "ground.h"
#include "queues.h"

/* A path that reached sphere light l: its radiance, MIS-weighted against the light's sampling when
 * the ray came from phase (or cosine) sampling (d.w its pdf; 0 for a camera ray, which takes it
 * whole), the pdf taken at the ray's origin times select_pmf (shade.cl's rule); seen from the camera
 * it is in the emission pass, after one scattering event in the direct pass. The path ends (dark
 * when its ray started inside the sphere). */
inline int sphere_light_hit(__constant const st_scene* scene, st_path* p, int l, __global float4* results) {
  __constant const st_light* light = &scene->lights[l];
  if (!(sphere_cone_omc(light, p->o.xyz) > 0.0f)) return ST_Q_FINISH;
  const float pdf_phase = p->d.w;
  const float w = pdf_phase > 0.0f ? power_heuristic(pdf_phase, light->select_pmf * sphere_light_pdf(light, p->o.xyz))
                                   : 1.0f;
  const float4 c = p->beta * path_mask(scene, p) * light_radiance(light, p->lambda) * w;
  p->L += c;
  const uint L = (uint)scene->result_layers;
  if (ST_HAS_AOV && L > ST_RESULT_LAYERS_AOV && p->depth <= 1)
    results[p->result_index * L + (p->depth == 0 ? ST_RESULT_EMISSION : ST_RESULT_DIRECT)] += c;
  return ST_Q_FINISH;
}

ST_STAGE_FUNCTION(track) {
  const uint cur = it.cur;
  uint slot = queue_item(queues, Q, NL, cur, ST_Q_TRACK, gid);
  st_path p;
  path_load(paths, Q, slot, ST_PATH_TRACK_READS, &p);
  st_rng rng = path_rng(scene, &p, 0u, p.rng_draw);
  if (ST_HAS_GUIDING) guide_rng_key(&rng, guide, guide_records, slot); /* a split path's streams */
  st_track_stats st;
  track_stats_clear(&st);
  float t = p.o.w;
  int medium = 0;
  float4 beta = p.beta, L = ST_PATH_TRACK_GATHERS ? p.L : (float4)(0.0f);
  float4 r_u = p.r_u;
  if (!spectral_mode(scene)) r_u.w = 0.0f; /* an unused lane: whatever the last launch left there */
  int sphere;
  const float t_surface = surface_distance(scene, p.o.xyz, p.d.xyz, &sphere);
  int ev = track_path(scene, grids, maj, p.o.xyz, p.d.xyz, &t, t_surface, &beta, &r_u, (int)p.channel, path_mask(scene, &p), &L,
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
  } else if ((ST_HAS_GROUND || ST_HAS_SPHERE_LIGHT) && ev == ST_EV_ESCAPE && t_surface < INFINITY) {
    q = sphere >= 0 ? sphere_light_hit(scene, &p, sphere, results) : ground_hit(scene, &p, t_surface);
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
  path_store(paths, Q, slot, ST_PATH_TRACK | ST_PATH_TRACK_GATHERS, &p);
  flush_track_stats(counters, &st, ST_C_LOOKUPS_TRACK);
  if (ST_HAS_PIXEL_WORK) pixel_work_add(scene, queues, Q, NL, p.pixel, st.lookups + st.dda_steps);
  queue_push(queues, counters, Q, NL, cur, q, slot);
}
