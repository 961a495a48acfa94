/* shade.cl: paths that left every medium see the lights at infinity (environment, sun discs),
 * weighted by MIS against next-event estimation when the direction came from phase sampling
 * (d.w holds that pdf; 0 for camera rays, which take the full radiance). Next-event estimation
 * reaches a light with its pdf times select_pmf (1 when every light gets a shadow ray). With the
 * alpha or environment layer, what a camera ray sees before any scattering goes to that layer. */
#include "types.h"
#include "features.h"
#include "sampling.h"
#include "spectrum.h"
#include "light.h"
#include "queues.h"

ST_STAGE_FUNCTION(escape) {
  const uint cur = it.cur;
  uint slot = queue_item(queues, Q, NL, cur, ST_Q_ESCAPE, gid);
  st_path p;
  path_load(paths, Q, slot, ST_PATH_ALL, &p);
  float3 d = p.d.xyz;
  float pdf_phase = p.d.w;
  float4 L = (float4)(0.0f);
  float4 lambda = p.lambda;
  const float4 mask = path_mask(scene, &p);
  for (int l = 0; l < scene->n_lights; ++l) {
    __constant const st_light* light = &scene->lights[l];
    float4 Le = light_Le(light, env, d, lambda);
    if (masked_max(Le, scene_lanes(scene)) <= 0.0f) continue;
    float w = pdf_phase > 0.0f ? power_heuristic(pdf_phase, light->select_pmf * light_pdf(light, env, d)) : 1.0f;
    L += Le * w;
  }
  /* the alpha / environment layers: lights at infinity seen straight from the camera go to the
   * environment layer (a transparent film, types.h ST_AOVS) */
  if (ST_HAS_AOV && scene->result_layers > 1 && p.depth == 0) {
    results[p.result_index * (uint)scene->result_layers + ST_RESULT_ENVIRONMENT] = p.beta * mask * L;
  } else {
    p.L += p.beta * mask * L;
    path_store(paths, Q, slot, ST_PATH_RADIANCE, &p);
    /* the direct pass: the lights that the first scattering event's phase-sampled ray reaches */
    if (ST_HAS_AOV && scene->result_layers > ST_RESULT_LAYERS_AOV && p.depth == 1)
      results[p.result_index * (uint)scene->result_layers + ST_RESULT_DIRECT] += p.beta * mask * L;
  }
  queue_push(queues, counters, Q, NL, cur, ST_Q_FINISH, slot);
}
