// settings.cpp: see settings.h. The tracker's properties come from the tracker table of
// kernels/types.h (ST_TRACKERS), which the kernels read too.
#include "integrator/settings.h"

#include <algorithm>
#include <cmath>
#include <fmt/format.h>

#include "guiding/guide_cache.h"
#include "integrator/noise.h"

namespace spectrack {

namespace {

// An enum choice given as a number (RenderOptions): its value, or an error naming it.
template <class E>
E checked_enum(int v, int count, const char* what) {
  if (v < 0 || v >= count) throw Error(fmt::format("{} {} does not exist", what, v));
  return E(v);
}

FilmWindow resolve_window(const SceneDesc& scene, const RenderOptions& o) {
  const int W = scene.film.width, H = scene.film.height;
  if (!o.pixel_bounds) return FilmWindow{0, 0, W, H};
  auto [x0, x1, y0, y1] = *o.pixel_bounds;
  if (!(0 <= x0 && x0 < x1 && 0 <= y0 && y0 < y1))
    throw Error(fmt::format("pixel bounds {},{},{},{} (x0,x1,y0,y1) are not a non-empty window", x0, x1, y0, y1));
  if (x1 > W || y1 > H)
    throw Error(fmt::format("--pixel-bounds {},{},{},{}: the window x {}..{}, y {}..{} leaves the {}x{} film of {} "
                            "(/film/width, /film/height)",
                            x0, x1, y0, y1, x0, x1 - 1, y0, y1 - 1, W, H, scene.path));
  return FilmWindow{x0, y0, x1 - x0, y1 - y0};
}

// Settings that do not go together: an error of the scene (exit 1, naming its file and `field`)
// when the scene alone asked for them, else a usage error of the options (exit 2).
[[noreturn]] void conflict(bool from_options, const SceneDesc& scene, const char* field, const std::string& why) {
  if (from_options) throw UsageError(why);
  throw Error(fmt::format("{}: {}: {}", scene.path, field, why));
}

// The noise target and adaptive sampling; a noise target is measured from the variance layer
// (integrator/noise.h), which it adds.
void resolve_noise_target(const SceneDesc& scene, const RenderOptions& o, RenderSettings& s) {
  s.noise_target = o.noise_target.value_or(scene.render.noise_target);
  if (!(s.noise_target >= 0 && s.noise_target <= 1))
    throw Error(fmt::format("noise target {} is not a relative error in (0, 1] (0: none)", s.noise_target));
  if (s.noise_target > 0) s.aovs |= ST_AOV_BIT(VARIANCE);
  // the command line's and the Python module's one check: a shard or tile would stop at its own
  // noise (and an adaptive one take its own rounds), so the pieces would not merge to the render
  if (s.noise_target > 0 && (o.sample_range || o.pixel_bounds))
    throw UsageError("--noise-target (render.noise_target) with --spp-range or --pixel-bounds (in Python: "
                     "spp_range=, pixel_bounds=): each shard or tile would stop at its own noise, and the pieces would not merge; "
                     "render the whole film");
  s.adaptive = o.adaptive.value_or(scene.render.adaptive);
  if (s.adaptive && s.noise_target <= 0)
    conflict(o.adaptive || o.noise_target, scene, "/render/adaptive",
             "adaptive sampling (--adaptive, render.adaptive) needs a noise target (--noise-target, "
             "render.noise_target): it gives each pixel the samples that bring it to that target");
}

// Equi-angular sampling asked for (the scene packer resolves auto): the option, else the scene,
// else kDefaultEquiangular; refused with guiding, whose scattered directions its MIS weights ignore.
EquiangularMode resolve_equiangular(const SceneDesc& scene, const RenderOptions& o, bool guiding) {
  const EquiangularMode e = o.equiangular ? checked_enum<EquiangularMode>(*o.equiangular, kEquiangularAuto + 1, "equi-angular mode")
                                          : scene.render.equiangular.value_or(kDefaultEquiangular);
  if (guiding && e == kEquiangularOn)
    conflict(o.equiangular || o.guiding, scene, "/render/equiangular",
             "equi-angular sampling does not work with guiding yet (its MIS weights assume phase "
             "sampling); use --equiangular off or auto, or --guiding off");
  return e;
}

// Guiding: on, off, or auto (guiding_pays, unless the render asks for what guiding refuses), and
// which samples of the sequence are the training passes' (RenderSettings::guide_training_samples).
// Every part of a render trains the same cache over the full film and samples 0 .. T - 1; a part
// keeps those samples only if its range holds all of them, so a sample range that cuts them is
// refused. A whole render of at most T samples trains one fewer (the render keeps one of its own);
// a shard of a longer render cannot know its total, so its range must hold T and one more, or none.
// `auto` depends on the scene and the options alone, so every part of a render resolves it alike.
void resolve_guiding(const RenderOptions& o, RenderSettings& s, const SceneDesc& scene) {
  s.guiding_requested = o.guiding ? checked_enum<GuidingMode>(*o.guiding, kGuidingAuto + 1, "guiding mode")
                                  : scene.render.guiding.value_or(kGuidingAuto);
  const int equiangular = o.equiangular ? *o.equiangular : int(scene.render.equiangular.value_or(kDefaultEquiangular));
  const bool local_lights = std::any_of(scene.lights.begin(), scene.lights.end(), [](const LightDesc& l) {
    return l.type == ST_LIGHT_POINT || l.type == ST_LIGHT_SPOT || l.type == ST_LIGHT_SPHERE;
  });
  // what guiding refuses or turns off (equi-angular sampling, which auto may turn on for local
  // lights), and a whole render of one sample (no training sample)
  const bool refused = o.film_state || equiangular == kEquiangularOn || (equiangular == kEquiangularAuto && local_lights) ||
                       (!o.sample_range && s.spp <= 1);
  const bool by_auto = s.guiding_requested == kGuidingAuto && !refused && guiding_pays(scene);
  s.guiding = s.guiding_requested == kGuidingOn || by_auto;
  // auto guides scattered directions alone unless asked to split: guided roulette and splitting
  // cost more than they save on every scene measured (docs/guiding.md)
  s.guide_splitting = s.guiding && o.guide_splitting.value_or(s.guiding_requested == kGuidingOn);
  if (!s.guiding) {  // what only a guided render uses is refused, not ignored
    const char* needs = "it needs guiding (--guiding on, render.guiding \"on\", or auto where it turns guiding on)";
    if (o.guide_splitting.value_or(false))
      throw UsageError(fmt::format("--guide-splitting on (guide_splitting=True) splits guided paths: {}", needs));
    if (!o.guide_cache_file.empty())
      throw UsageError(fmt::format("--guide-cache FILE (guide_cache=) holds a trained guide cache: {}", needs));
    return;
  }
  const GuideTraining schedule = guide_training_setting();
  if (!o.guide_cache_file.empty() && schedule.spp.size() != 1)
    throw UsageError("--guide-cache works with one training pass (the default), not SPECTRACK_GUIDE_TRAINING's several");
  int T = schedule.samples();
  // adaptive sampling trains in its pilot round, which must hold the training samples and one more
  if (s.adaptive) T = std::min<int64_t>(T, std::min<int64_t>(kNoiseMinSpp, s.spp) - 1);
  const int64_t begin = s.sample_begin, end = s.sample_begin + s.spp;
  if (begin == 0 && !o.sample_range) {
    if (s.spp <= 1)  // auto is off there (refused above), so guiding was asked for
      conflict(o.guiding || o.spp, scene, "/render/guiding",
               "--guiding on (render.guiding \"on\") needs at least 2 samples per pixel: the first trains "
               "the guide cache and the render's own samples follow it; with --spp 1 use --guiding off or auto");
    s.guide_training_samples = std::min(T, s.spp - 1);
  } else if (begin == 0 ? end <= T : begin < T) {
    throw UsageError(fmt::format("guiding{}: samples {}:{} cut the training pass's samples 0:{}; a shard of a guided "
                                 "render holds all of them and at least one more, or none of them (--spp-range 0:B "
                                 "with B > {}, or A:B with A >= {}{}); a guided render of at most {} samples is not cut "
                                 "into sample ranges (render it whole)",
                                 by_auto ? " (on by auto: the scene has a lamp, a medium that emits and does not scatter)" : "",
                                 begin, end, T, T, T, by_auto ? ", or --guiding off" : "", T + 1));
  } else {
    s.guide_training_samples = T;
  }
}

}  // namespace

bool guiding_pays(const SceneDesc& scene) {
  auto positive = [](const Vec3& v) { return v[0] > 0 || v[1] > 0 || v[2] > 0; };
  // sigma_s as the packer makes it: times density_scale, and an albedo colour grid makes a medium
  // of sigma_s 0 scatter (sigma_t times the albedo)
  auto scatters = [&](const MediumDesc& m) {
    return m.density_scale > 0 &&
           (positive(m.sigma_s) || (m.color.present && m.color.mode == ST_COLOR_ALBEDO && positive(m.sigma_a)));
  };
  // a source term that is not 0: a colour (a radiance, a blackbody above its cutoff, a ramp with a
  // stop above 0) times sigma_a (the physical model) or the density (the artists' model)
  auto emits = [&](const MediumDesc& m) {
    const EmissionDesc& e = m.emission;
    return e.colour_nonzero() && m.density_scale > 0 && (e.per_density || positive(m.sigma_a));
  };
  auto lamp = [&](const MediumDesc& m) { return emits(m) && !scatters(m); };
  auto glows = [&](const MediumDesc& m) { return emits(m) && scatters(m); };
  const auto& media = scene.media;
  return std::any_of(media.begin(), media.end(), lamp) && std::any_of(media.begin(), media.end(), scatters) &&
         std::none_of(media.begin(), media.end(), glows);
}

RenderSettings resolve_settings(const SceneDesc& scene, const RenderOptions& o) {
  RenderSettings s;
  // the enum choices: the option (a number, checked here), else the scene, else the default
  s.tracker = o.tracker ? checked_enum<st_tracker>(*o.tracker, ST_TRACKER_COUNT, "tracker") : scene.render.tracker;
  s.scheme = o.scheme ? checked_enum<st_scheme>(*o.scheme, ST_SCHEME_COUNT, "spectral scheme") : scene.render.scheme;
  // a tracker without a scheme runs the analog probabilities (kernels/tracking.h): record those
  if (!st_tracker_uses_scheme(s.tracker)) s.scheme = ST_SCHEME_MAX;
  s.absorption = o.absorption ? checked_enum<st_absorption>(*o.absorption, ST_ABSORPTION_COUNT, "absorption mode")
                              : scene.render.absorption.value_or(st_absorption(st_tracker_default_absorption(s.tracker)));
  s.light_sampling = o.light_sampling
                         ? checked_enum<st_light_sampling>(*o.light_sampling, ST_LIGHT_SAMPLING_COUNT, "light sampling mode")
                         : scene.render.light_sampling.value_or(kDefaultLightSampling);
  s.transmittance =
      o.transmittance ? checked_enum<st_transmittance_mode>(*o.transmittance, ST_TRANSMITTANCE_COUNT, "transmittance estimator")
                      : scene.render.transmittance.value_or(kDefaultTransmittance);
  s.lookup = o.lookup ? checked_enum<st_lookup_mode>(*o.lookup, ST_LOOKUP_COUNT, "density lookup mode")
                      : scene.render.lookup.value_or(kDefaultLookup);
  s.color = o.color ? checked_enum<st_film_color>(*o.color, ST_FILM_COLOR_COUNT, "colour mode") : scene.render.color;
  s.wavelength_sampling = o.wavelength_sampling ? checked_enum<st_wavelength_sampling>(*o.wavelength_sampling,
                                                                                       ST_WAVELENGTH_SAMPLING_COUNT,
                                                                                       "wavelength sampling")
                                                : scene.render.wavelength_sampling.value_or(kDefaultWavelengthSampling);
  s.march_spacing = o.march_spacing.value_or(kDefaultMarchSpacing);
  s.pilot_spacing = o.pilot_spacing.value_or(kDefaultPilotSpacing);
  // below 1e-3 a sample per thousandth of an optical depth; above 1e3 one sample per ray
  for (auto [name, v] : {std::pair<const char*, double>{"--march-spacing", s.march_spacing}, {"--pilot-spacing", s.pilot_spacing}})
    if (!(v >= 1e-3 && v <= 1e3))
      throw Error(fmt::format("{} {}: the majorant optical depth between ray-marching samples must be in [0.001, 1000]",
                              name, v));
  // film layers: the option, else film.aovs with film.alpha (library default: no alpha; the CLI
  // turns it on for EXR outputs); alpha makes the film transparent, so the environment layer
  // holds what RGB leaves out
  s.aovs = o.aovs ? *o.aovs : (scene.film.aovs | (scene.film.alpha.value_or(false) ? uint32_t(ST_AOV_BIT(ALPHA)) : 0u));
  if (s.aovs >= (1u << ST_AOV_COUNT)) throw Error(fmt::format("film layer mask 0x{:x} names layers that do not exist", s.aovs));
  if (scene.ground.present && scene.ground.mode == ST_GROUND_SHADOW_CATCHER) s.aovs |= ST_AOV_BIT(SHADOW);  // ground.h
  if (s.aovs & ST_AOV_BIT(ALPHA)) s.aovs |= ST_AOV_BIT(ENVIRONMENT);
  resolve_noise_target(scene, o, s);
  s.seed = o.seed ? uint32_t(*o.seed) : scene.render.seed;
  s.spp = o.spp.value_or(scene.film.spp);
  s.shutter = o.shutter ? o.shutter : scene.camera.shutter;
  if (s.shutter && !(std::isfinite((*s.shutter)[0]) && std::isfinite((*s.shutter)[1]) && (*s.shutter)[1] >= (*s.shutter)[0]))
    throw Error(fmt::format("shutter {}:{}: expected finite open <= close (seconds)", (*s.shutter)[0], (*s.shutter)[1]));
  s.time_strata = scene.film.spp;
  s.iteration_budget = o.iteration_budget;
  s.majorant_cell = o.majorant_cell;
  s.majorant_block = o.majorant_block;
  s.majorant_step_cost = o.majorant_step_cost;
  s.sample_begin = o.sample_begin;
  if (s.sample_begin < 0 || s.spp < 1 || uint64_t(s.sample_begin) + uint64_t(s.spp) > (uint64_t(1) << 32))
    throw Error(fmt::format("sample range {}:{} is not a non-empty range of sample indices 0 .. 2^32", s.sample_begin,
                            s.sample_begin + s.spp));
  s.window = resolve_window(scene, o);
  s.full_width = scene.film.width;
  s.full_height = scene.film.height;
  s.channels_per_sample = st_paths_per_sample(s.tracker, s.color);
  resolve_guiding(o, s, scene);
  s.equiangular = resolve_equiangular(scene, o, s.guiding);
  if (st_tracker_achromatic_only(s.tracker)) {
    for (auto& m : scene.media) {
      if (!achromatic(m.sigma_a) || !achromatic(m.sigma_s))
        throw Error(fmt::format("{}: {}: tracker '{}' needs achromatic media (equal sigma_a and sigma_s in every "
                                "channel); medium '{}' is chromatic: use delta-per-channel or spectral",
                                scene.path, m.json_path, tracker_name(s.tracker), m.name));
      else if (m.color.present)
        throw Error(fmt::format("{}: {}/color: tracker '{}' needs achromatic media; medium '{}' has a colour grid, "
                                "which makes its coefficients differ by channel: use delta-per-channel or spectral",
                                scene.path, m.json_path, tracker_name(s.tracker), m.name));
    }
  }
  return s;
}

}  // namespace spectrack
