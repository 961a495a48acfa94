/* ground.h: the surfaces a ray can end at: the ground, an infinite horizontal plane y = height
 * (st_scene.ground; features.h ST_HAS_GROUND) that faces up and is opaque (everything below it is
 * hidden), and the sphere lights (light.h; ST_HAS_SPHERE_LIGHT), opaque emitters that a path
 * reaching one ends at (track.cl sphere_light_hit). surface_distance gives the nearest along a
 * ray, the t_max of every walk along it; surface_blocks tells a shadow ray that one stops it.
 *
 * Design: the ground is where a walk ends. A path's free-path sampling (track.cl) and every
 * transmittance estimate along a camera ray (raygen.cl) run to the plane's distance along the ray
 * as their t_max (the walker clips its segments there, as it does at a local light), and a path
 * that leaves the media there becomes a surface vertex: st_path.medium = ST_MEDIUM_GROUND on the
 * scatter queue (ground_hit). A diffuse ground is a Lambertian reflector: k_scatter samples the
 * lights there with f = albedo cos / pi (MIS against cosine sampling by the power heuristic, whose
 * pdf cos / pi the escaping ray's d.w carries, as a phase sample's), then continues the path with a
 * cosine sample (beta *= albedo). A shadow ray from a point above the plane towards a light below
 * its horizon (or a local light under it) is blocked (ground_blocks); from the ground itself f = 0
 * there. A ray that starts below the plane (a camera under the ground) ends at once, black.
 *
 * Shadow catcher and holdout: the ground is transparent for the film (the alpha layer is
 * 1 - the camera ray's transmittance up to it) and adds nothing to the beauty; every path that
 * reaches it ends there (it still occludes). A camera ray that reaches a shadow catcher takes one
 * light sample per light there (scatter.cl shadow_catcher_event), each the unshadowed estimate
 * E = f Le / pdf of the light's direct irradiance (no MIS, no albedo: they cancel in the ratio);
 * ST_RESULT_UNSHADOWED sums E and ST_RESULT_SHADOW sums E T, T the shadow ray's transmittance, and
 * the shadow layer is their ratio per pixel (both are film sums: shards and merges stay exact). */
#ifndef SPECTRACK_GROUND_H
#define SPECTRACK_GROUND_H

#include "types.h"
#include "features.h"
#include "sampling.h"
#include "spectrum.h"
#include "light.h"

#define ST_INV_PI 0.31830988618379067f

inline int ground_present(__constant const st_scene* scene) { return ST_HAS_GROUND && scene->ground.present; }

/* Distance along the ray (o, d) (d unit) to the ground: 0 when o is below it, INFINITY when the
 * ray never reaches it (or there is none). */
inline float ground_distance(__constant const st_scene* scene, float3 o, float3 d) {
  if (!ground_present(scene)) return INFINITY;
  const float h = scene->ground.height;
  if (o.y < h) return 0.0f;
  return d.y < 0.0f ? (h - o.y) / d.y : INFINITY;
}

/* Whether the ground stops a shadow ray from o (a point above it, not on it) along wi before t_max. */
inline int ground_blocks(__constant const st_scene* scene, float3 o, float3 wi, float t_max) {
  return ground_present(scene) && ground_distance(scene, o, wi) < t_max;
}

/* The nearest surface along (o, d): its distance (INFINITY: none), *sphere the sphere light's index
 * when it is one, else -1 (the ground, or none). */
inline float surface_distance(__constant const st_scene* scene, float3 o, float3 d, int* sphere) {
  float t = ground_distance(scene, o, d);
  *sphere = -1;
  if (ST_HAS_SPHERE_LIGHT)
    for (int l = 0; l < ST_MAX_LIGHTS; ++l) {
      if (l >= scene->n_lights || scene->lights[l].type != ST_LIGHT_SPHERE) continue;
      const float ts = sphere_distance(&scene->lights[l], o, d);
      if (ts < t) t = ts, *sphere = l;
    }
  return t;
}

/* Whether a surface stops the shadow ray from o along wi before t_max: the ground (not tested from
 * a ground vertex, whose cosine already removes what lies below it) or a sphere light other than
 * the light `target` the ray goes to. */
inline int surface_blocks(__constant const st_scene* scene, float3 o, float3 wi, float t_max, int from_ground,
                          int target) {
  if (!from_ground && ground_blocks(scene, o, wi, t_max)) return 1;
  if (ST_HAS_SPHERE_LIGHT)
    for (int l = 0; l < ST_MAX_LIGHTS; ++l) {
      if (l >= scene->n_lights || l == target || scene->lights[l].type != ST_LIGHT_SPHERE) continue;
      if (sphere_distance(&scene->lights[l], o, wi) < t_max) return 1;
    }
  return 0;
}

/* The ground's albedo at the path's wavelengths (rgb mode: its rgb). */
inline float4 ground_albedo(__constant const st_scene* scene, float4 lambda) {
  return scene->ground.spectral ? spectrum_at(scene->ground.albedo, lambda) : scene->ground.albedo;
}

/* cos / pi towards wi (the ground's normal is +y): the Lambertian BRDF over the albedo, times the
 * cosine, and the pdf of cosine sampling. */
inline float ground_cos_over_pi(float3 wi) { return fmax(wi.y, 0.0f) * ST_INV_PI; }

/* A cosine-distributed direction above the ground (Malley's method on the concentric disc). */
inline float3 ground_sample_cosine(float u1, float u2) {
  const float2 q = sample_concentric_disk(u1, u2);
  return (float3)(q.x, sqrt(fmax(0.0f, 1.0f - q.x * q.x - q.y * q.y)), q.y);
}

/* A path whose walk (t_max = t_ground) left the media at the ground: the queue it goes to. A
 * diffuse ground, or a shadow catcher seen by the camera ray, is a surface vertex (scatter queue,
 * the origin on the plane exactly); a holdout, a shadow catcher reached after scattering and a ray
 * that started under the ground end (finish queue). */
inline int ground_hit(__constant const st_scene* scene, st_path* p, float t_ground) {
  if (p->o.y < scene->ground.height) return ST_Q_FINISH;
  const int mode = scene->ground.mode;
  if (mode == ST_GROUND_HOLDOUT || (mode == ST_GROUND_SHADOW_CATCHER && p->depth > 0)) return ST_Q_FINISH;
  const float3 x = p->o.xyz + t_ground * p->d.xyz;
  p->o = (float4)(x.x, scene->ground.height, x.z, 0.0f);
  p->medium = ST_MEDIUM_GROUND;
  return ST_Q_SCATTER;
}

#endif
