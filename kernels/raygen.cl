/* raygen.cl: fills free path slots with camera paths. Path g (a 64-bit index over the whole
 * render) is (batch, sample, pixel, channel); its random stream depends only on those, so which
 * slot it lands in never changes the image. The launch covers the n_new slots it fills, the top
 * of the free stack (queues.h: places n_free - n_new .. n_free - 1); the free slots below them are
 * not touched and stay free. */
#include "types.h"
#include "features.h"
#include "rng.h"
#include "spectrum.h"
#include "medium.h"
#include "majorant.h"
#include "walker.h"
#include "tracking.h"
#include "transmittance.h"
#include "ground.h"
#include "queues.h"
#include "equiangular.h"
#include "sampling.h"


/* The camera ray's first collision for the albedo and depth layers (types.h ST_AOVS): a delta-tracking
 * free flight whose collision density is sigma_t T with sigma_t the mean over the lanes (channels or wavelengths) of the
 * extinction (every medium, no decomposition), on its own stream ST_STREAM_CAMERA_COLLISION. A
 * tentative collision of the walker (rate mu_bar, the channels' majorant) is real with probability
 * sigma_t / (sigma_t + |mu_bar - sigma_t|), and the flight's weight w takes the ratio of
 * probabilities (weighted delta tracking, as the trackers handle majorant_scale < 1): w stays 1
 * wherever mu_bar bounds sigma_t, the usual case. Returns w at the first real collision, with *aux =
 * w (sigma_s / sigma_t per channel, distance) there (a channel with sigma_t = 0 has albedo 0), or 0
 * when the ray leaves every medium. One walk, its budget unbounded (it ends at the first real
 * collision or at the last medium; the walker's exact position sum keeps it moving). Lookups count
 * as the camera layers' (density_lookups_alpha). The walk ends at the nearest surface (ground.h);
 * a diffuse ground there is the collision: its albedo at its distance. */
inline float camera_first_collision(__constant const st_scene* scene, __global const uint* grids,
                                    __global const float2* maj, __global uint* counters, const st_path* p,
                                    float4* aux) {
  const float4 all = scene_lanes(scene);
  const float3 o = p->o.xyz, d = p->d.xyz;
  st_rng rng = path_rng(scene, p, ST_STREAM_CAMERA_COLLISION, 0u);
  st_track_stats st;
  track_stats_clear(&st);
  st_walker w;
  int sphere;
  const float t_surface = surface_distance(scene, o, d, &sphere);
  walker_begin(scene, maj, &w, o, d, 0.0f, t_surface, all, rng.lambda, 0, ST_WALK_SAMPLE_CONTROL, INT_MAX);
  float weight = 1.0f, hit = 0.0f;
  for (;;) {
    int step = walker_step(scene, maj, &w, &rng, &st.dda_steps, &st.dda_nonempty);
    if (step == ST_WALK_DONE || step == ST_WALK_BUDGET) break;
    if (step != ST_WALK_COLLISION) continue;
    st_medium_point c = medium_sample_point(scene, grids, o + w.t * d, &st.lookups, 0, &rng, w.sigma_a_l, w.sigma_s_l);
    float4 sigma_t = c.sigma_a + c.sigma_s;
    float sigma_t_mean = fmax(spectral_mode(scene) ? (sigma_t.x + sigma_t.y + sigma_t.z + sigma_t.w) * 0.25f
                                                   : (sigma_t.x + sigma_t.y + sigma_t.z) * (1.0f / 3.0f),
                              0.0f);
    float sigma_n = w.mu_bar - sigma_t_mean;
    float P_real = sigma_t_mean / (sigma_t_mean + fabs(sigma_n));
    if (rng_uniform(&rng) < P_real) {
      if (sigma_n < 0.0f) weight *= sigma_t_mean / (w.mu_bar * P_real); /* else exactly 1 */
      float4 albedo = select((float4)(0.0f), c.sigma_s / sigma_t, sigma_t > 0.0f);
      if (spectral_mode(scene)) /* a reflectance under D65, as linear sRGB (finish.cl keeps it) */
        albedo = film_rgb(albedo * d65_at(rng.lambda), rng.lambda, wavelength_pdfs(rng.lambda), 4);
      *aux = weight * (float4)(albedo.xyz, w.t);
      hit = weight;
      break;
    }
    if (sigma_n < 0.0f) weight *= sigma_n / (w.mu_bar * (1.0f - P_real)); /* else exactly 1 */
  }
  if (ST_HAS_GROUND && hit == 0.0f && sphere < 0 && t_surface < INFINITY && scene->ground.mode == ST_GROUND_DIFFUSE) {
    *aux = weight * (float4)(scene->ground.albedo_rgb.xyz, t_surface);
    hit = weight;
  }
  counter_add(counters, ST_C_LOOKUPS_ALPHA, st.lookups);
  return hit;
}

/* The camera layers of a new camera path (types.h ST_AOVS): the environment
 * (and the emission and direct passes) start at 0 (k_escape, k_track and the shadow folds add to them), the alpha value is 1 - T per channel with T the scene's
 * transmittance estimator along the whole camera ray (ratio tracking or ray marching, through
 * every medium, every lane at once), on the stream ST_STREAM_CAMERA_T so the path's own stream is unchanged. It runs to the end here
 * (roulette bounds it); its lookups are counted on their own (density_lookups_alpha). The albedo
 * and depth layers take the ray's first collision (camera_first_collision). The estimate ends at
 * the nearest surface (ground.h); a diffuse ground or a sphere light there is opaque: alpha 1. */
inline void camera_layers_begin(__constant const st_scene* scene, __global const uint* grids,
                                __global const float2* maj, __global uint* counters, __global float4* results,
                                __global uint* queues, uint Q, uint NL, const st_path* p) {
  const uint L = (uint)scene->result_layers;
  __global float4* r = &results[p->result_index * L];
  r[ST_RESULT_ENVIRONMENT] = (float4)(0.0f);
  if (L > ST_RESULT_LAYERS_AOV) r[ST_RESULT_EMISSION] = r[ST_RESULT_DIRECT] = (float4)(0.0f);
  if (L > ST_RESULT_UNSHADOWED) r[ST_RESULT_SHADOW] = r[ST_RESULT_UNSHADOWED] = (float4)(0.0f);
  float4 alpha = (float4)(0.0f);
  /* one estimate per sample, for every channel: the per-channel trackers' channel-0 path makes it
   * (the sample's other paths add 0), the others carry every channel already */
  if ((scene->aovs & ST_AOV_BIT(ALPHA)) && (scene->n_channels_per_sample == 1 || p->channel == 0u)) {
    const float4 all = scene_lanes(scene);
    st_rng rng = path_rng(scene, p, ST_STREAM_CAMERA_T, 0u);
    st_track_stats st;
    track_stats_clear(&st);
    st_trans tr;
    transmittance_begin(&tr, all);
    float t = 0.0f;
    int sphere;
    const float t_surface = surface_distance(scene, p->o.xyz, p->d.xyz, &sphere);
    while (!transmittance_estimate(scene, grids, maj, p->o.xyz, p->d.xyz, t_surface, &t, &tr, all, all, &rng,
                                   scene->iteration_budget, &st)) {
    }
    alpha = all - tr.T;
    /* opaque: a sphere light, a diffuse ground */
    if ((ST_HAS_GROUND || ST_HAS_SPHERE_LIGHT) && t_surface < INFINITY &&
        (sphere >= 0 || scene->ground.mode == ST_GROUND_DIFFUSE))
      alpha = all;
    if (spectral_mode(scene)) /* 1 - T at the four wavelengths, a reflectance under D65, as linear sRGB */
      alpha = film_rgb(alpha * d65_at(rng.lambda), rng.lambda, wavelength_pdfs(rng.lambda), 4);
    alpha.w = 0.0f;
    counter_add(counters, ST_C_LOOKUPS_ALPHA, st.lookups);
    if (ST_HAS_PIXEL_WORK) pixel_work_add(scene, queues, Q, NL, p->pixel, st.lookups + st.dda_steps);
  }
  /* albedo and depth: one free flight of the channel-mean extinction along the camera ray, scored
   * at its first real collision (camera_first_collision); its weight goes to alpha's w */
  if (L > ST_RESULT_LAYERS_PASSES) {
    float4 aux = (float4)(0.0f);
    if ((scene->aovs & (ST_AOV_BIT(ALBEDO) | ST_AOV_BIT(DEPTH))) &&
        (scene->n_channels_per_sample == 1 || p->channel == 0u))
      alpha.w = camera_first_collision(scene, grids, maj, counters, p, &aux);
    r[ST_RESULT_AUX] = aux;
  }
  r[ST_RESULT_ALPHA] = alpha;
}

/* The camera (types.h st_camera) is given at shutter open. A thin lens (pbrt-v4's lensradius and
 * focaldistance) moves each ray's origin to a point of the lens disc and aims it at the point its
 * pinhole ray reaches at the focus distance along forward; a moving camera lerps position and
 * look_at with the path's time in the shutter (queues.h path_shutter_u).
 *
 * The camera's frame at the path's time: its own at shutter open, or, for a moving camera
 * (st_camera.moving), position and look_at lerped to the time and the frame rebuilt around the
 * given up with the same scales (|right|, |up|) as at open. */
inline void camera_frame(__constant const st_camera* cam, const st_path* p, __constant const st_scene* scene,
                         float3* position, float3* forward, float3* right, float3* up) {
  *position = cam->position.xyz;
  *forward = cam->forward.xyz;
  *right = cam->right.xyz;
  *up = cam->up.xyz;
  if (ST_HAS_TIME && cam->moving) {
    const float u = path_shutter_u(scene, p->pixel, p->sample);
    *position = mix(cam->position.xyz, cam->position1.xyz, u);
    const float3 f = normalize(mix(cam->look_at0.xyz, cam->look_at1.xyz, u) - *position);
    const float3 r = normalize(cross(f, cam->up_world.xyz));
    *forward = f;
    *right = cam->look_at0.w * r;
    *up = cam->look_at1.w * cross(r, f);
  }
}

/* The camera ray through film point (x + jx, y + jy). A pinhole's (lens radius 0) starts at the
 * camera position (perspective) or on the camera plane (orthographic); a thin lens (pbrt-v4's
 * PerspectiveCamera and OrthographicCamera) moves its origin by a uniform point of the lens disc,
 * in the frame's unit right and up, and aims it at the point the pinhole ray reaches at the focus
 * distance along forward, which therefore stays sharp; the lens point comes from the path's
 * stream ST_STREAM_LENS, so the path's own stream is that of the pinhole. */
inline void camera_ray(__constant const st_scene* scene, const st_path* p, int x, int y, float jx, float jy,
                       float3* o, float3* d) {
  __constant const st_camera* cam = &scene->camera;
  float sx = 2.0f * ((float)x + jx) / (float)cam->width - 1.0f;
  float sy = 1.0f - 2.0f * ((float)y + jy) / (float)cam->height;
  float3 position, forward, right, up;
  camera_frame(cam, p, scene, &position, &forward, &right, &up);
  float3 pinhole_d; /* along forward, with a forward component of 1 */
  if (cam->type == ST_CAMERA_ORTHOGRAPHIC) {
    *o = position + sx * right + sy * up;
    pinhole_d = forward;
    *d = forward;
  } else {
    *o = position;
    pinhole_d = forward + sx * right + sy * up;
    *d = normalize(pinhole_d);
  }
  const float lens_radius = cam->position.w;
  if (ST_HAS_THIN_LENS && lens_radius > 0.0f) {
    st_rng lr = path_rng(scene, p, ST_STREAM_LENS, 0u);
    const float u1 = rng_uniform(&lr), u2 = rng_uniform(&lr);
    const float2 l = lens_radius * sample_concentric_disk(u1, u2);
    const float3 focus = *o + cam->forward.w * pinhole_d;
    *o += l.x * normalize(right) + l.y * normalize(up);
    *d = normalize(focus - *o);
  }
}

ST_STAGE_FUNCTION(raygen) {
  const uint cur = it.cur, n_new = it.n_new;
  uint slot = queues[free_offset(Q) + free_base(it.n_queue[ST_Q_FREE], n_new) + gid];
  ulong g = it.first + gid;
  uint nch = (uint)scene->n_channels_per_sample;
  uint npix = (uint)(scene->window_width * scene->window_height);
  const uint batch_paths = it.batch_paths;
  /* adaptive sampling: a batch is whole samples of the listed pixels only */
  if (ST_HAS_ADAPTIVE) npix = batch_paths / (it.samples_per_batch * nch);
  ulong b = g / batch_paths;
  uint in_batch = (uint)(g - b * batch_paths);
  uint ch = in_batch % nch;
  uint wpix = (in_batch / nch) % npix;
  uint s_local = in_batch / (nch * npix);
  if (ST_HAS_ADAPTIVE) { /* an entry of the list: its pixel, its first sample (queues.h) */
    const uint e = active_pixels_offset(scene, Q, NL) + 2u * wpix;
    wpix = queues[e];
    s_local += queues[e + 1u];
  }

  st_path p;
  p.sample = it.sample_begin + (uint)b * it.samples_per_batch + s_local;
  int x = scene->pixel_x0 + (int)(wpix % (uint)scene->window_width);
  int y = scene->pixel_y0 + (int)(wpix / (uint)scene->window_width);
  p.pixel = (uint)(y * scene->camera.width + x);
  p.channel = nch > 1u ? ch : 0u;
  const uint batch = (uint)(b % (ulong)scene->batches_in_flight); /* its ring slot: finish.cl */
  p.result_index = batch * batch_paths + in_batch;
  p.lambda = spectral_mode(scene) ? path_wavelengths(scene, &p) : (float4)(0.0f);
  st_rng rng = path_rng(scene, &p, 0u, 0u);
  float jx = rng_uniform(&rng), jy = rng_uniform(&rng);

  float3 o, d;
  camera_ray(scene, &p, x, y, jx, jy, &o, &d);
  p.o = (float4)(o, 0.0f);
  p.d = (float4)(d, 0.0f);
  /* spectral-mis: the hero channel, uniform (the one-sample MIS's choice of technique, tracking.h) */
  if (tracker_is_mis(scene)) p.channel = (uint)draw_hero(scene, &rng);
  p.beta = path_mask(scene, &p);
  p.L = (float4)(0.0f);
  p.rng_draw = rng_draw_index(&rng);
  p.depth = 0;
  p.pending = 0;
  p.medium = 0;
  p.r_u = scene_lanes(scene);
  if (ea_on(scene)) ea_begin(scene, grids, env, shadows, queues, counters, Q, NL, cur, slot, &p);
  path_store(paths, Q, slot, ST_PATH_ALL, &p);
  if (ST_HAS_AOV && scene->result_layers > 1) camera_layers_begin(scene, grids, maj, counters, results, queues, Q, NL, &p);
  st_shadow acc; /* the lights' accumulators start empty */
  acc.Ls = (float4)(0.0f);
  for (uint l = 0; l < (uint)shadow_lights(scene); ++l) shadow_store(shadows, Q * NL, slot * NL + l, ST_SHADOW_LS, &acc);
  if (ST_HAS_GUIDING) guide_split_begin(guide, guide_records, slot);
  queue_push(queues, counters, Q, NL, cur, ST_Q_TRACK, slot);
}
