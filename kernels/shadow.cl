/* shadow.cl: transmittance of a next-event-estimation ray through the majorant grid by the
 * scene's estimator (ratio tracking or ray marching, transmittance.h), resumable across launches; when
 * done, marks its entry done (the path adds weight * T to its light's accumulator: queues.h) and
 * releases the path. */
#include "types.h"
#include "features.h"
#include "rng.h"
#include "sampling.h"
#include "tracking.h"
#include "transmittance.h"
#include "guiding.h"
#include "queues.h"
#include "equiangular.h"

/* The groups of its entry (shadow_state.h) that k_shadow reads: the ray, the weight (roulette's
 * importance), the estimate, the stream and owner, and with equi-angular sampling the leg and
 * light. It writes back what changed: a finished estimate its T and the state; a resumed one the
 * ray's t, the estimate and the draw; leg 2 of an equi-angular entry also the new ray, the weight
 * and the leg. */
#define ST_SHADOW_EA_LEGS (ST_HAS_EQUIANGULAR ? ST_SHADOW_WEIGHT | ST_SHADOW_EA : 0)
#define ST_SHADOW_TRACE_READS \
  (ST_SHADOW_RAY | ST_SHADOW_WEIGHT | ST_SHADOW_TRANS | ST_SHADOW_KEY | (ST_HAS_EQUIANGULAR ? ST_SHADOW_EA : 0))
#define ST_SHADOW_TRACE_DONE (ST_SHADOW_T | ST_SHADOW_STATUS | ST_SHADOW_EA_LEGS)
#define ST_SHADOW_TRACE_RESUME (ST_SHADOW_RAY | ST_SHADOW_TRANS | ST_SHADOW_KEY | ST_SHADOW_EA_LEGS)

ST_STAGE_FUNCTION(shadow) {
  const uint cur = it.cur, n = Q * NL;
  uint id = queue_item(queues, Q, NL, cur, ST_Q_SHADOW, gid);
  st_shadow sh;
  shadow_load(shadows, n, id, ST_SHADOW_TRACE_READS, &sh);
  st_path p;
  path_load(paths, Q, sh.slot, ST_PATH_SHADOW_READS, &p);
  st_rng rng = path_rng(scene, &p, sh.stream, sh.rng_draw);
  if (ST_HAS_GUIDING) guide_rng_key(&rng, guide, guide_records, sh.slot); /* a split path's streams */
  st_track_stats st;
  track_stats_clear(&st);
  float t = sh.o.w;
  /* roulette by what the estimate is for: weight * T per channel, relative to the weight's largest
   * channel (transmittance.h transmittance_roulette); the weight is never 0 (scatter.cl) */
  const float4 mask = path_mask(scene, &p), w = fabs(sh.weight);
  const float w_max = masked_max(w, mask);
  const float4 importance = w_max > 0.0f ? w / w_max : mask;
  int done = transmittance_estimate(scene, grids, maj, sh.o.xyz, sh.d.xyz, sh.t_max, &t, &sh.tr, mask, importance, &rng,
                                    scene->iteration_budget, &st);
  if (done && ST_HAS_EQUIANGULAR && sh.ea_leg == 1u) { /* an equi-angular entry's leg 1 (equiangular.h) */
    done = ea_second_leg(scene, env, &sh, &p, mask);
    t = 0.0f;
  }
  sh.rng_draw = rng_draw_index(&rng);
  if (done) {
    sh.state = ST_SHADOW_DONE;
    shadow_store(shadows, n, id, ST_SHADOW_TRACE_DONE, &sh);
    atomic_dec(path_pending(paths, Q, sh.slot));
  } else {
    sh.o.w = t;
    shadow_store(shadows, n, id, ST_SHADOW_TRACE_RESUME, &sh);
    atomic_inc(&counters[ST_C_REQUEUES]);
    queue_push(queues, counters, Q, NL, cur, ST_Q_SHADOW, id);
  }
  flush_track_stats(counters, &st, ST_C_LOOKUPS_SHADOW);
  if (ST_HAS_PIXEL_WORK) pixel_work_add(scene, queues, Q, NL, p.pixel, st.lookups + st.dda_steps);
}
