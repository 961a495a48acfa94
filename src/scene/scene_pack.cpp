// scene_pack.cpp: see scene_pack.h. pack_scene runs the packer's parts (packer.h: media in
// pack_media.cpp, lights in pack_lights.cpp, the camera in pack_camera.cpp), sets the render
// constants and derives the scene's feature mask.
#include "scene/packer.h"
#include "scene/scene_pack.h"
#include "scene/spectral_pack.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>

#include "color/spectrum.h"
#include "image/image.h"
#include "scene/radiance.h"
#include "volume/float_limits.h"
#include "scene/media_bounds.h"
#include "integrator/memory_budget.h"
#include "scene/framing.h"
#include "volume/volume.h"

namespace spectrack {
namespace packing {

uint32_t Packer::scene_features() const {
  uint32_t f = 0;
  if (st.n_media > 1) f |= ST_FEATURE_MULTI_MEDIUM;
  for (int i = 0; i < st.n_media; ++i) {
    const st_medium& m = st.media[i];
    if (m.emissive) f |= ST_FEATURE_EMISSION;
    // exactly what the kernels see: the float coefficients
    bool gray = m.sigma_a.x == m.sigma_a.y && m.sigma_a.y == m.sigma_a.z && m.sigma_s.x == m.sigma_s.y &&
                m.sigma_s.y == m.sigma_s.z;
    if (!gray) f |= ST_FEATURE_CHROMATIC;
    if (m.color_mode != ST_COLOR_NONE) f |= ST_FEATURE_COLOR | ST_FEATURE_CHROMATIC;
    if (m.phase_type == ST_PHASE_HG) f |= ST_FEATURE_HG;
    if (m.phase_type == ST_PHASE_DRAINE_BLEND) f |= ST_FEATURE_PHASE_SET;
    if (m.type == ST_MEDIUM_VDB) f |= ST_FEATURE_VDB;
    if (m.maj_block > 0) f |= ST_FEATURE_COARSE_MAJORANT;
    if (m.type == ST_MEDIUM_VDB && m.velocity_grid[0] != ST_NO_GRID) f |= ST_FEATURE_VELOCITY | ST_FEATURE_TIME;
  }
  for (int i = 0; i < st.n_lights; ++i) {
    const st_light& l = st.lights[i];
    if (l.type == ST_LIGHT_ENV_MAP) f |= ST_FEATURE_ENV_MAP;
    if (l.type == ST_LIGHT_SPHERE) f |= ST_FEATURE_SPHERE_LIGHT;  // rays that reach one end there: no escape
    if (l.type >= ST_LIGHT_POINT) {
      f |= ST_FEATURE_LOCAL_LIGHT;  // delta in direction or hit at a finite distance: no escaping ray sees one
      continue;
    }
    if (l.type != ST_LIGHT_DIRECTIONAL || !l.is_delta) f |= ST_FEATURE_ESCAPE;
  }
  if (st_tracker_decomposes(st.tracker)) f |= ST_FEATURE_DECOMPOSITION;
  if (st.tracker == ST_TRACKER_SPECTRAL_MIS) f |= ST_FEATURE_SPECTRAL_MIS;
  if (st.transmittance == ST_TRANSMITTANCE_RAY_MARCHING) f |= ST_FEATURE_RAY_MARCHING;
  if (st.lookup == ST_LOOKUP_STOCHASTIC && (f & ST_FEATURE_VDB)) f |= ST_FEATURE_STOCHASTIC_LOOKUP;
  if (st.result_layers > 1) f |= ST_FEATURE_AOV;
  if (st.ground.present) f |= ST_FEATURE_GROUND;
  if (st.equiangular.n_local > 0) f |= ST_FEATURE_EQUIANGULAR | ST_FEATURE_LOCAL_LIGHT;
  return f | camera_features;
}

}  // namespace packing

PackedScene pack_scene(const SceneDesc& scene, const RenderSettings& s, const PackOptions& options) {
  if (options.iteration_budget < 1) throw Error("iteration budget must be at least 1");
  if (options.majorant_cell < 0) throw Error("majorant cell must be 0 (automatic) or at least 1 voxel");
  if (options.majorant_block < 0) throw Error("majorant block must be 0 (one level) or at least 1 cell");
  if (options.majorant_step_cost && !(std::isfinite(*options.majorant_step_cost) && *options.majorant_step_cost >= 0))
    throw Error(fmt::format("majorant step cost {} must be a finite number of density lookups, at least 0 (leave it "
                            "out for the automatic one)",
                            *options.majorant_step_cost));
  PackedScene out;
  st_scene& st = out.st;
  std::memset(&st, 0, sizeof(st));
  packing::Packer pk{scene, options, st, out.grid_words, out.maj_cells, out.env_data, out.majorants, s.tracker,
            s.color == ST_FILM_COLOR_SPECTRAL};
  st.n_media = int(scene.media.size());
  st.n_lights = int(scene.lights.size());
  if (s.shutter) pk.shutter_reach = std::max(std::abs((*s.shutter)[0]), std::abs((*s.shutter)[1]));
  pk.stochastic_lookup = s.lookup == ST_LOOKUP_STOCHASTIC;
  for (int i = 0; i < st.n_media; ++i) pk.add_medium(i, scene.media[i]);
  for (int i = 0; i < st.n_lights; ++i) pk.add_light(i, scene.lights[i]);
  if (scene.ground.present) {  // kernels/ground.h
    const Vec3& a = scene.ground.albedo;
    st.ground.present = 1;
    st.ground.height = float(scene.ground.height);
    st.ground.mode = scene.ground.mode;
    st.ground.albedo = st.ground.albedo_rgb = st_float4{float(a[0]), float(a[1]), float(a[2]), 0.0f};
  }
  pk.set_equiangular(s.guiding ? kEquiangularOff : s.equiangular);
  const int light_sampling = pk.resolve_light_sampling(s.light_sampling);
  pk.set_light_selection(light_sampling);
  pk.set_camera(s);
  check_coordinates(scene, st, pk.media_boxes, pk.camera_position);  // volume/float_limits.h
  st.tracker = s.tracker;
  st.scheme = s.scheme;
  st.absorption = s.absorption;
  st.light_sampling = light_sampling;
  st.transmittance = s.transmittance;
  st.march_spacing = float(s.march_spacing);
  st.pilot_spacing = float(s.pilot_spacing);
  st.lookup = s.lookup;
  st.wavelength_sampling = s.wavelength_sampling;
  st.wavelength_sample_offset = s.guide_training_samples;  // the render's own samples follow the training's
  st.aovs = int(s.aovs);
  st.result_layers = (s.aovs & ST_AOV_BIT(SHADOW))                         ? ST_RESULT_LAYERS_SHADOW
                     : (s.aovs & (ST_AOV_BIT(ALBEDO) | ST_AOV_BIT(DEPTH))) ? ST_RESULT_LAYERS_AUX
                     : (s.aovs & (ST_AOV_BIT(EMISSION) | ST_AOV_BIT(DIRECT) | ST_AOV_BIT(INDIRECT)))
                         ? ST_RESULT_LAYERS_PASSES
                         : (s.aovs & (ST_AOV_BIT(ALPHA) | ST_AOV_BIT(ENVIRONMENT))) ? ST_RESULT_LAYERS_AOV : 1;
  st.max_depth = scene.render.max_depth.value_or(-1);  // -1: unlimited
  st.seed = s.seed;
  st.n_channels_per_sample = s.channels_per_sample;
  st.iteration_budget = options.iteration_budget;
  st.batches_in_flight = 2;  // set per render
  st.pixel_x0 = s.window.x0;
  st.pixel_y0 = s.window.y0;
  st.window_width = s.window.width;
  st.window_height = s.window.height;
  for (auto& l : scene.lights) st.has_env |= (l.type == ST_LIGHT_ENV_UNIFORM || l.type == ST_LIGHT_ENV_MAP);
  for (auto& m : scene.media) st.chromatic |= !(achromatic(m.sigma_a) && achromatic(m.sigma_s));
  if (out.maj_cells.empty()) out.maj_cells = {0.0f, 0.0f};
  if (out.grid_words.empty()) out.grid_words = {0u, 0u};
  if (out.env_data.empty()) out.env_data = {0.0f};
  out.features = pk.scene_features();
  // spectral mode: the colours the kernels read become spectra, once everything above has been
  // derived from the rgb values (spectral_pack.h)
  if (s.color == ST_FILM_COLOR_SPECTRAL) make_spectral(scene, out);
  return out;
}

}  // namespace spectrack

