// scene_media.cpp: the media and lights of a spectrack-scene/1 file (docs/scene-format.md):
// each medium's type, coefficients, grids, phase function, emission, colour and transform, and
// each light, read by the Parser of scene_parser.h.
#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <iomanip>
#include <limits>
#include <map>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>

#include "scene/scene_parser.h"
#include "scene/phase_models.h"
#include "scene/presets.h"
#include "scene/radiance.h"
#include "util/files.h"
#include "scene/frames.h"
#include "util/strings.h"

namespace spectrack {
namespace parsing {

LightDesc Parser::light(const json& j, const std::string& path) {
  expect_object(j, path);
  const Names all = {"type",      "radiance", "map",      "scale",          "rotate_deg",    "to_light",      "irradiance",
                     "angle_deg", "position", "intensity", "look_at", "cone_angle_deg", "cone_delta_deg", "radius",
                     "sun_elevation_deg", "sun_azimuth_deg", "altitude", "air_density", "dust_density",
                     "ozone_density", "sun_disc", "sun_angle_deg", "resolution"};
  fields(j, path, all);
  LightDesc l;
  l.json_path = path;
  need(j, path, "type", "expected one of: environment, directional, point, spot, sphere, sky");
  std::string type = string(j, path, "type", "");
  if (type == "environment") {
    fields(j, path, {"type", "radiance", "map", "scale", "rotate_deg"}, "an environment light", all);
    if (find(j, "map")) {
      if (find(j, "radiance")) fail(path + "/radiance", "not allowed together with \"map\" (use \"scale\")");
      l.type = ST_LIGHT_ENV_MAP;
      l.map = file(j, path, "map", true);
      l.scale = number(j, path, "scale", l.scale, kNonNegative);
      l.rotate_deg = number(j, path, "rotate_deg", l.rotate_deg, Range{-360, 360, false, false});
    } else {
      for (const char* key : {"scale", "rotate_deg"})
        if (find(j, key)) fail(path + "/" + key, "only allowed with \"map\"");
      l.type = ST_LIGHT_ENV_UNIFORM;
      l.radiance = vec3(j, path, "radiance", l.radiance, kNonNegative);
    }
  } else if (type == "directional") {
    fields(j, path, {"type", "to_light", "irradiance", "angle_deg"}, "a directional light", all);
    l.type = ST_LIGHT_DIRECTIONAL;
    l.to_light = vec3_at(need(j, path, "to_light"), path + "/to_light", kAny);
    if (l.to_light[0] == 0 && l.to_light[1] == 0 && l.to_light[2] == 0) fail(path + "/to_light", "must not be zero");
    l.irradiance = vec3(j, path, "irradiance", l.irradiance, kNonNegative);
    l.angle_deg = number(j, path, "angle_deg", l.angle_deg, Range{0, 180, false, true});
  } else if (type == "point" || type == "spot") {
    local_light(j, path, type == "spot", all, l);
  } else if (type == "sphere") {  // an emitting sphere: centre, radius (world units), surface radiance
    fields(j, path, {"type", "position", "radius", "radiance"}, "a sphere light", all);
    l.type = ST_LIGHT_SPHERE;
    l.position = vec3_at(need(j, path, "position"), path + "/position", kAny);
    l.radius = number_at(need(j, path, "radius"), path + "/radius", Range{0, 1.15e18, true, false});
    l.radiance = vec3(j, path, "radiance", l.radiance, kNonNegative);
  } else if (type == "sky") {
    sky_light(j, path, all, l);
  } else {
    fail(path + "/type",
         "unknown light type " + in_quotes(type) + " (expected one of: environment, directional, point, spot, sphere, sky)");
  }
  return l;
}

// The ground (kernels/ground.h): height (world units, within 2^60 as every coordinate), albedo in
// [0, 1] per channel, mode.
GroundDesc Parser::ground(const json& j, const std::string& path) {
  expect_object(j, path);
  fields(j, path, {"height", "albedo", "mode"});
  GroundDesc g;
  g.present = true;
  g.height = number(j, path, "height", g.height, Range{-1.15e18, 1.15e18, false, false});
  g.albedo = vec3(j, path, "albedo", g.albedo, Range{0, 1, false, false});
  const std::string mode = string(j, path, "mode", ground_mode_name(g.mode));
  g.mode = ground_mode_from_name(mode);
  if (g.mode < 0)
    fail(path + "/mode", "unknown ground mode " + in_quotes(mode) + " (expected one of: " + ground_mode_names() + ")");
  return g;
}

// A point or spot light (kernels/light.h): position and intensity (W/sr); a spot's axis towards
// look_at, its cone angle in (0, 180] degrees and a falloff width in [0, cone_angle].
void Parser::local_light(const json& j, const std::string& path, bool spot, const Names& all, LightDesc& l) {
  if (spot)
    fields(j, path, {"type", "position", "intensity", "look_at", "cone_angle_deg", "cone_delta_deg"}, "a spot light", all);
  else
    fields(j, path, {"type", "position", "intensity"}, "a point light", all);
  l.type = spot ? ST_LIGHT_SPOT : ST_LIGHT_POINT;
  l.position = vec3_at(need(j, path, "position"), path + "/position", kAny);
  l.intensity = vec3(j, path, "intensity", l.intensity, kNonNegative);
  if (!spot) return;
  l.look_at = vec3_at(need(j, path, "look_at"), path + "/look_at", kAny);
  if (l.look_at == l.position) fail(path + "/look_at", "must differ from position (it gives the cone's axis)");
  for (int k = 0; k < 3; ++k)
    if (!std::isfinite(l.look_at[k] - l.position[k]))
      fail(path + "/look_at", "is so far from position that the axis between them overflows (" + num(l.look_at[k]) +
                                  " - " + num(l.position[k]) + ")");
  l.cone_angle_deg = number(j, path, "cone_angle_deg", l.cone_angle_deg, Range{0, 180, true, false});
  l.cone_delta_deg = number(j, path, "cone_delta_deg", std::min(l.cone_delta_deg, l.cone_angle_deg), kNonNegative);
  if (l.cone_delta_deg > l.cone_angle_deg)
    fail(path + "/cone_delta_deg", "value " + num(l.cone_delta_deg) + " is more than cone_angle_deg (" +
                                       num(l.cone_angle_deg) + ")");
}

// A physical sky (color/sky.h): the sun's place, the atmosphere's densities, the viewer's altitude,
// an intensity for sky and sun, the sun's disc and the map's resolution. Its environment map is
// made when the scene is packed; the sun follows it as a directional light (scene.cpp).
void Parser::sky_light(const json& j, const std::string& path, const Names& all, LightDesc& l) {
  fields(j, path,
         {"type", "sun_elevation_deg", "sun_azimuth_deg", "altitude", "air_density", "dust_density", "ozone_density",
          "intensity", "sun_disc", "sun_angle_deg", "resolution"},
         "a sky", all);
  l.type = ST_LIGHT_ENV_MAP;
  SkyDesc k;
  k.sun_elevation_deg = number(j, path, "sun_elevation_deg", k.sun_elevation_deg, Range{-90, 90, false, false});
  k.sun_azimuth_deg = number(j, path, "sun_azimuth_deg", k.sun_azimuth_deg, Range{-360, 360, false, false});
  k.atmosphere.altitude_m = number(j, path, "altitude", 0.0, Range{0, 59000, false, false});
  k.atmosphere.air = number(j, path, "air_density", 1.0, Range{0, 10, false, false});
  k.atmosphere.dust = number(j, path, "dust_density", 1.0, Range{0, 10, false, false});
  k.atmosphere.ozone = number(j, path, "ozone_density", 1.0, Range{0, 10, false, false});
  k.intensity = number(j, path, "intensity", k.intensity, Range{0, 1e12, false, false});
  if (const json* v = find(j, "sun_disc")) {
    if (!v->is_boolean()) fail(path + "/sun_disc", std::string("expected true or false, got ") + v->type_name());
    k.sun_disc = v->get<bool>();
  }
  k.sun_angle_deg = number(j, path, "sun_angle_deg", k.sun_angle_deg, Range{0, 10, false, false});
  k.resolution = static_cast<int>(integer(j, path, "resolution", k.resolution, 16, 8192));
  if (k.resolution % 2) fail(path + "/resolution", "value " + std::to_string(k.resolution) + " is odd (the map is resolution x resolution / 2)");
  l.scale = k.intensity;
  l.sky = k;
}

MediumDesc Parser::medium(const json& j, const std::string& path, size_t index) {
  expect_object(j, path);
  const Names all = {"name", "type", "file", "file_source", "grid", "grid_index", "bounds", "density_scale", "sigma_s",
                     "sigma_a", "phase", "emission", "color", "velocity", "transform", "majorant_scale",
                     "minorant_scale", "preset"};
  Names vdb, homogeneous;
  for (const char* k : all) {
    if (std::strcmp(k, "bounds") != 0) vdb.push_back(k);
    if (!contains({"file", "file_source", "grid", "grid_index", "transform", "color", "velocity", "preset"}, k))
      homogeneous.push_back(k);
  }
  fields(j, path, all);

  MediumDesc m;
  m.json_path = path;
  m.name = string(j, path, "name", "medium" + std::to_string(index));
  context_ = ", in medium " + in_quotes(m.name);
  need(j, path, "type", "expected \"vdb\" or \"homogeneous\"");
  std::string type = string(j, path, "type", "");
  if (type == "vdb") {
    fields(j, path, vdb, "a vdb medium", all);
    m.type = ST_MEDIUM_VDB;
    need(j, path, "file", "the .vdb or .nvdb file");
    string(j, path, "file_source", "");  // a string when present (quoted when the file is missing)
    m.file = file(j, path, "file", true);
    if (find(j, "preset")) {
      m.preset = string(j, path, "preset", "");
      if (!apply_medium_preset(m.preset, &m))
        fail(path + "/preset", "unknown preset " + in_quotes(m.preset) + " (expected one of: " + medium_preset_names() + ")");
    }
    m.grid = string(j, path, "grid", m.grid);
    m.grid_index = static_cast<int>(integer(j, path, "grid_index", m.grid_index, 0, std::numeric_limits<int>::max()));
    if (const json* t = find(j, "transform")) m.transform = transform(*t, path + "/transform");
    if (const json* c = find(j, "color")) m.color = color(*c, path + "/color");
    if (const json* v = find(j, "velocity")) m.velocity = velocity(*v, path + "/velocity");
  } else if (type == "homogeneous") {
    fields(j, path, homogeneous, "a homogeneous medium", all);
    m.type = ST_MEDIUM_HOMOGENEOUS;
    const json& b = need(j, path, "bounds", "[[xmin, ymin, zmin], [xmax, ymax, zmax]]");
    if (!b.is_array() || b.size() != 2)
      fail(path + "/bounds", "expected [[xmin, ymin, zmin], [xmax, ymax, zmax]]");
    m.bounds = {vec3_at(b[0], path + "/bounds/0", kAny), vec3_at(b[1], path + "/bounds/1", kAny)};
    for (int a = 0; a < 3; ++a)
      if (!(m.bounds[0][a] < m.bounds[1][a]))
        fail(path + "/bounds", std::string("min >= max on the ") + "xyz"[a] + " axis (" + num(m.bounds[0][a]) +
                                   " >= " + num(m.bounds[1][a]) + ")");
  } else {
    fail(path + "/type", "unknown medium type " + in_quotes(type) + " (expected one of: vdb, homogeneous)");
  }
  m.density_scale = number(j, path, "density_scale", m.density_scale, kNonNegative);
  m.sigma_s = vec3(j, path, "sigma_s", m.sigma_s, kNonNegative);
  m.sigma_a = vec3(j, path, "sigma_a", m.sigma_a, kNonNegative);
  if (const json* p = find(j, "phase")) m.phase = phase(*p, path + "/phase");
  if (const json* e = find(j, "emission")) m.emission = emission(*e, path + "/emission", m.type == ST_MEDIUM_VDB);
  if (m.emission.per_density) {
    if (!(m.sigma_a[0] > 0 && m.sigma_a[0] == m.sigma_a[1] && m.sigma_a[1] == m.sigma_a[2]))
      fail(path + "/emission/model", "\"density\" needs a grey sigma_a > 0 (equal channels; the absorption's own "
                                     "brightness is divided out): sigma_a is [" + num(m.sigma_a[0]) + ", " + num(m.sigma_a[1]) +
                                     ", " + num(m.sigma_a[2]) + "]");
    if (m.color.present) fail(path + "/emission/model", "\"density\" excludes a colour grid (it varies sigma_a per voxel)");
  } else if (m.emission.colour_nonzero() && !(m.color.present && m.color.mode == ST_COLOR_ALBEDO) &&
             !(m.sigma_a[0] > 0 || m.sigma_a[1] > 0 || m.sigma_a[2] > 0)) {  // an albedo grid makes sigma_a
    fail(path + "/emission", "the absorption model (the default \"model\") emits sigma_a times the emission's colour, "
                             "and sigma_a is [0, 0, 0]: the medium would emit nothing; give sigma_a > 0");
  }
  m.majorant_scale = number(j, path, "majorant_scale", m.majorant_scale, kPositive);
  m.minorant_scale = number(j, path, "minorant_scale", m.minorant_scale, kNonNegative);
  context_.clear();
  return m;
}

PhaseDesc Parser::phase(const json& j, const std::string& path) {
  expect_object(j, path);
  const Names all = {"type", "g", "alpha", "g1", "g2", "w", "diameter_um"};
  fields(j, path, all);
  const char* kTypes = "isotropic, hg, draine, rayleigh, hg2, mie";
  need(j, path, "type", std::string("expected one of: ") + kTypes);
  std::string type = string(j, path, "type", "");
  const Range open_g{-1, 1, true, true};
  auto g_at = [&](const char* key) {
    return number_at(need(j, path, key, "an asymmetry, in (-1, 1)"), path + "/" + key, open_g);
  };
  PhaseDesc p;
  if (type == "isotropic") {
    fields(j, path, {"type"}, "an isotropic phase function", all);
  } else if (type == "hg") {
    fields(j, path, {"type", "g"}, "an hg phase function", all);
    p.type = ST_PHASE_HG;
    p.g = g_at("g");
  } else if (type == "draine") {
    fields(j, path, {"type", "g", "alpha"}, "a draine phase function", all);
    const double g = g_at("g");
    p = draine_phase(g, number_at(need(j, path, "alpha", "Draine's alpha, in [0, 1000]"), path + "/alpha",
                                  Range{0, 1000, false, false}));
  } else if (type == "rayleigh") {
    fields(j, path, {"type"}, "a rayleigh phase function", all);
    p = rayleigh_phase();
  } else if (type == "hg2") {
    fields(j, path, {"type", "g1", "g2", "w"}, "an hg2 phase function", all);
    const double g1 = g_at("g1"), g2 = g_at("g2");
    p = hg2_phase(g1, g2, number_at(need(j, path, "w", "the second lobe's weight, in [0, 1]"), path + "/w",
                                    Range{0, 1, false, false}));
  } else if (type == "mie") {
    fields(j, path, {"type", "diameter_um"}, "a mie phase function", all);
    const double d = number_at(need(j, path, "diameter_um", "the water droplets' diameter in micrometres, in [5, 50]"),
                               path + "/diameter_um", Range{kMieMinDiameterUm, kMieMaxDiameterUm, false, false});
    p = mie_phase(d);
  } else {
    fail(path + "/type", "unknown phase function " + in_quotes(type) + " (expected one of: " + kTypes + ")");
  }
  p.name = type;
  return p;
}


EmissionDesc Parser::ramp(const json& j, const std::string& path, bool vdb, EmissionDesc e) {
  const Names all = {"type", "grid", "stops", "scale", "model"};
  fields(j, path, all);
  if (!vdb) fail(path + "/type", "a ramp maps a grid's values: vdb media only");
  e.ramp = true;
  e.grid = string(j, path, "grid", "");
  if (e.grid.empty()) fail(path + "/grid", "required: the float grid whose values the ramp maps (e.g. heat, flame)");
  e.scale = number(j, path, "scale", e.scale, kNonNegative);
  const json& stops = need(j, path, "stops", "[[value, [r, g, b]], ...]");
  if (!stops.is_array() || stops.empty() || stops.size() > 64)
    fail(path + "/stops", "expected 1 to 64 stops [[value, [r, g, b]], ...]");
  for (size_t i = 0; i < stops.size(); ++i) {
    const std::string at = path + "/stops/" + std::to_string(i);
    if (!stops[i].is_array() || stops[i].size() != 2) fail(at, "expected [value, [r, g, b]]");
    const double v = number_at(stops[i][0], at + "/0", kAny);
    if (!e.stops.empty() && !(v > e.stops.back().first))
      fail(at + "/0", "value " + num(v) + " must be greater than the previous stop's (" + num(e.stops.back().first) + ")");
    if (!e.stops.empty() && !std::isfinite(v - e.stops.front().first))  // the interpolation divides by spans
      fail(at + "/0", "value " + num(v) + " is too far from the first stop's (" + num(e.stops.front().first) +
                          "): the span between them overflows a double");
    e.stops.push_back({v, vec3_at(stops[i][1], at + "/1", kNonNegative)});
  }
  return e;
}

EmissionDesc Parser::emission(const json& j, const std::string& path, bool vdb) {
  expect_object(j, path);
  EmissionDesc e;
  e.present = true;
  const std::string type = string(j, path, "type", "radiance");
  const std::string model = string(j, path, "model", "absorption");
  if (model != "absorption" && model != "density")
    fail(path + "/model", "unknown emission model " + in_quotes(model) + " (expected one of: absorption, density)");
  e.per_density = model == "density";
  if (type == "ramp") return ramp(j, path, vdb, e);
  if (type == "radiance") {
    const Names all = {"type", "grid", "radiance", "scale", "model"};
    fields(j, path, all);
    if (!vdb) fields(j, path, {"type", "radiance", "scale", "model"}, "a homogeneous medium's emission", all);
    e.grid = string(j, path, "grid", "");
    e.radiance = vec3_at(need(j, path, "radiance"), path + "/radiance", kNonNegative);
    e.scale = number(j, path, "scale", e.scale, kNonNegative);
    return e;
  }
  if (type != "blackbody")
    fail(path + "/type", "unknown emission type " + in_quotes(type) + " (expected one of: radiance, blackbody, ramp)");
  const Names all = {"type",        "scale",           "temperature",        "temperature_grid", "temperature_scale",
                     "temperature_offset", "temperature_cutoff", "normalization", "model"};
  fields(j, path, all);
  const Names constant = {"type", "scale", "temperature", "temperature_cutoff", "normalization", "model"};
  if (!vdb) fields(j, path, constant, "a homogeneous medium's blackbody emission (a constant `temperature`)", all);
  e.blackbody = true;
  // at most kMaxRadiance: the kernels hold scale x colour in float, colours <= ~1e6
  e.scale = number(j, path, "scale", e.scale, Range{0, kMaxRadiance, false, false});
  e.temperature_cutoff = number(j, path, "temperature_cutoff", e.temperature_cutoff, Range{0, kMaxTemperature, true, true});
  if (find(j, "temperature")) {
    if (find(j, "temperature_grid") || find(j, "temperature_scale") || find(j, "temperature_offset"))
      fail(path + "/temperature", "a constant temperature excludes temperature_grid, temperature_scale and "
                                  "temperature_offset (they map a grid's values)");
    e.temperature = number(j, path, "temperature", 0.0, Range{0, kMaxTemperature, true, false});
  } else if (!vdb) {
    fail(path + "/temperature", "required: a homogeneous medium's blackbody emission needs a constant temperature (K)");
  } else {
    e.temperature_grid = string(j, path, "temperature_grid", "");
    e.temperature_scale = number(j, path, "temperature_scale", e.temperature_scale, kAny);
    e.temperature_offset = number(j, path, "temperature_offset", e.temperature_offset, kAny);
  }
  const std::string norm = string(j, path, "normalization", blackbody_norm_name(BlackbodyNorm::Peak));
  if (!blackbody_norm_from_name(norm, &e.normalization))
    fail(path + "/normalization",
         "unknown normalization " + in_quotes(norm) + " (expected one of: " + blackbody_norm_names() + ")");
  return e;
}

ColorDesc Parser::color(const json& j, const std::string& path) {
  expect_object(j, path);
  fields(j, path, {"grid", "mode"});
  ColorDesc c;
  c.present = true;
  c.grid = string(j, path, "grid", c.grid);
  if (c.grid.empty()) fail(path + "/grid", "must name a vec3 grid of the medium's file");
  const std::string mode = string(j, path, "mode", "albedo");
  if (mode == "albedo") {
    c.mode = ST_COLOR_ALBEDO;
  } else if (mode == "scattering") {
    c.mode = ST_COLOR_SCATTERING;
  } else {
    fail(path + "/mode", "unknown colour mode " + in_quotes(mode) + " (expected one of: albedo, scattering)");
  }
  return c;
}

VelocityDesc Parser::velocity(const json& j, const std::string& path) {
  expect_object(j, path);
  fields(j, path, {"grid", "scale", "fps", "outlier_threshold"});
  VelocityDesc v;
  v.present = true;
  v.grid = string(j, path, "grid", v.grid);
  if (v.grid.empty()) fail(path + "/grid", "must name a vec3s velocity grid of the medium's file");
  v.scale = number(j, path, "scale", v.scale, kAny);
  v.fps = number(j, path, "fps", v.fps, kPositive);
  v.outlier_threshold = number(j, path, "outlier_threshold", v.outlier_threshold, kPositive);
  return v;
}

TransformDesc Parser::transform(const json& j, const std::string& path) {
  expect_object(j, path);
  fields(j, path, {"scale", "rotate_deg", "translate"});
  TransformDesc t;
  if (const json* s = find(j, "scale")) {
    const std::string p = path + "/scale";
    if (s->is_number()) {
      double v = number_at(*s, p, kAny);
      t.scale = {v, v, v};
    } else if (s->is_array()) {
      t.scale = vec3_at(*s, p, kAny);
    } else {
      fail(p, std::string("expected a number or an array of 3 numbers, got ") + s->type_name());
    }
    for (double v : t.scale)
      if (v == 0) fail(p, "scale must not be zero");
  }
  t.rotate_deg = vec3(j, path, "rotate_deg", t.rotate_deg, kAny);
  t.translate = vec3(j, path, "translate", t.translate, kAny);
  return t;
}

}  // namespace parsing
}  // namespace spectrack
