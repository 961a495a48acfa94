// scene.cpp: loading and validating spectrack-scene/1 files (docs/scene-format.md is the reference).
//
// Design: nlohmann::json parses the text with a callback that rejects duplicate keys (the library
// would silently keep the last one); then one Parser walks the tree top-down. Each object is first
// checked against the union of the fields it may have, so a typo is reported before anything
// else, and again against the fields of its `type` once that is known. Values are read through a
// few typed getters that know their JSON path, and every failure goes through Parser::fail, which
// writes "<scene>: <json path>: <reason>" (plus `, in medium "<name>"` inside a medium). Files the
// scene names are resolved against the scene's folder and must exist, but are not opened here:
// src/volume loads the grids and src/image the environment map.
#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <iomanip>
#include <limits>
#include <type_traits>
#include <map>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>

#include "integrator/option_table.h"
#include "scene/scene.h"
#include "scene/scene_parser.h"
#include "scene/sky_light.h"
#include "scene/radiance.h"
#include "util/files.h"
#include "scene/frames.h"
#include "util/strings.h"

namespace spectrack {
namespace parsing {

long long Parser::integer(const json& obj, const std::string& path, const char* key, long long def, long long lo,
                          long long hi) const {
  const json* v = find(obj, key);
  if (!v) return def;
  const std::string p = child(path, key);
  if (!v->is_number()) fail(p, std::string("expected an integer, got ") + v->type_name());
  const std::string range = " is out of range (must be in [" + std::to_string(lo) + ", " + std::to_string(hi) + "])";
  long long value = 0;
  if (v->is_number_unsigned()) {
    auto u = v->get<unsigned long long>();
    if (u > static_cast<unsigned long long>(hi)) fail(p, "value " + std::to_string(u) + range);
    value = static_cast<long long>(u);
  } else if (v->is_number_integer()) {
    value = v->get<long long>();
  } else {
    // 512.0 or 1e3 are integers written as floats; 0.5 is not.
    double d = v->get<double>();
    if (!std::isfinite(d) || std::floor(d) != d) fail(p, "expected an integer, got " + num(d));
    if (d < static_cast<double>(lo) || d > static_cast<double>(hi)) fail(p, "value " + num(d) + range);
    value = static_cast<long long>(d);
  }
  if (value < lo || value > hi) fail(p, "value " + std::to_string(value) + range);
  return value;
}

SceneDesc Parser::scene(const json& root) {
  expect_object(root, "");
  // The format is checked first: for some other JSON file it is the one useful message.
  const json& format = need(root, "", "format", std::string("expected ") + in_quotes(kFormat));
  if (!format.is_string()) fail("/format", std::string("expected a string, got ") + format.type_name());
  if (format.get<std::string>() != kFormat)
    fail("/format", "unsupported format " + in_quotes(format.get<std::string>()) + " (expected " + in_quotes(kFormat) + ")");
  fields(root, "", {"format", "camera", "film", "render", "lights", "media", "ground"});

  SceneDesc s;
  s.dir = dir_.string();
  if (const json* j = find(root, "camera")) camera(*j, "/camera", s.camera);
  if (const json* j = find(root, "film")) film(*j, "/film", s.film);
  else s.film.output = normalized(dir_ / s.film.output).string();
  if (const json* j = find(root, "render")) render(*j, "/render", s.render);
  if (const json* j = find(root, "ground")) s.ground = ground(*j, "/ground");

  if (const json* lights = find(root, "lights")) {
    if (!lights->is_array()) fail("/lights", std::string("expected an array, got ") + lights->type_name());
    if (lights->size() > ST_MAX_LIGHTS)
      fail("/lights", std::to_string(lights->size()) + " lights given, at most " + std::to_string(ST_MAX_LIGHTS) +
                          " (ST_MAX_LIGHTS) are supported");
    std::string env_path;
    for (size_t i = 0; i < lights->size(); ++i) {
      std::string path = child("/lights", i);
      s.lights.push_back(light((*lights)[i], path));
      const int type = s.lights.back().type;
      if (type != ST_LIGHT_ENV_UNIFORM && type != ST_LIGHT_ENV_MAP) continue;
      if (!env_path.empty())
        fail(path, "only one environment light is allowed (the first is " + env_path + ")");
      env_path = path;
      if (s.lights.back().sky)  // a sky's sun: a light of its own
        if (std::optional<LightDesc> sun = sky_sun_light(s.lights.back())) s.lights.push_back(*sun);
    }
    if (s.lights.size() > ST_MAX_LIGHTS)
      fail("/lights", std::to_string(s.lights.size()) + " lights with the sky's sun, at most " +
                          std::to_string(ST_MAX_LIGHTS) + " (ST_MAX_LIGHTS) are supported");
  }

  if (const json* media = find(root, "media")) {
    if (!media->is_array()) fail("/media", std::string("expected an array, got ") + media->type_name());
    if (media->size() > ST_MAX_MEDIA)
      fail("/media", std::to_string(media->size()) + " media given, at most " + std::to_string(ST_MAX_MEDIA) +
                         " (ST_MAX_MEDIA) are supported");
    std::map<std::string, std::string> names;  // name -> path of its medium
    for (size_t i = 0; i < media->size(); ++i) {
      std::string path = child("/media", i);
      s.media.push_back(medium((*media)[i], path, i));
      auto inserted = names.emplace(s.media.back().name, path);
      if (!inserted.second)
        fail(path + "/name",
             "duplicate medium name " + in_quotes(s.media.back().name) + " (also used by " + inserted.first->second + ")");
    }
  }
  return s;
}

void Parser::camera(const json& j, const std::string& path, CameraDesc& c) {
  expect_object(j, path);
  const Names all = {"type", "position", "look_at", "up", "fov_deg", "height", "fit", "aperture_radius",
                     "focus_distance", "shutter", "position_close", "look_at_close"};
  fields(j, path, all);
  std::string type = string(j, path, "type", "perspective");
  if (type == "perspective") {
    c.type = ST_CAMERA_PERSPECTIVE;
    fields(j, path, {"type", "position", "look_at", "up", "fov_deg", "fit", "aperture_radius", "focus_distance",
                     "shutter", "position_close", "look_at_close"}, "a perspective camera", all);
    c.fov_deg = number(j, path, "fov_deg", c.fov_deg, Range{0, 180, true, true});
  } else if (type == "orthographic") {
    c.type = ST_CAMERA_ORTHOGRAPHIC;
    fields(j, path, {"type", "position", "look_at", "up", "height", "fit", "aperture_radius", "focus_distance",
                     "shutter", "position_close", "look_at_close"}, "an orthographic camera", all);
    c.height = number(j, path, "height", c.height, kPositive);
  } else {
    fail(path + "/type", "unknown camera type " + in_quotes(type) + " (expected one of: perspective, orthographic)");
  }
  camera_framing(j, path, c);
  if (!c.position_auto) c.position = vec3(j, path, "position", c.position, kAny);
  if (!c.look_at_media) c.look_at = vec3(j, path, "look_at", c.look_at, kAny);
  c.up = vec3(j, path, "up", c.up, kAny);
  camera_lens_time(j, path, c);
  const double ulen = vec3_length(c.up);
  if (c.position_auto || c.look_at_media) {  // the view direction is known once the media are (scene/framing.h)
    if (!(ulen > 0)) fail(path + "/up", "is zero");
    return;
  }
  check_view(path, "", c.position, c.look_at, c.up);
  if (c.position_close || c.look_at_close)
    check_view(path, " at shutter close", c.position_close.value_or(c.position), c.look_at_close.value_or(c.look_at),
               c.up);
}

// A view direction look_at - position that exists and is not parallel to up.
void Parser::check_view(const std::string& path, const std::string& at, const Vec3& position, const Vec3& look_at,
                        const Vec3& up) {
  const Vec3 d{look_at[0] - position[0], look_at[1] - position[1], look_at[2] - position[2]};
  if (d == Vec3{0, 0, 0})
    fail(path + (at.empty() ? "/look_at" : "/look_at_close"), "equals the camera position" + at + " (no view direction)");
  // a difference beyond the doubles is a position beyond the coordinate bound, which the packer's
  // checks name (volume/float_limits.h)
  if (!std::isfinite(d[0]) || !std::isfinite(d[1]) || !std::isfinite(d[2])) return;
  if (!(vec3_length(up) > 0)) fail(path + "/up", "is zero");
  // |d x up| = |d| |up| sin(angle), of unit vectors (any lengths): parallel below a small angle
  const Vec3 f = unit_vector(d), u = unit_vector(up);
  const Vec3 x{f[1] * u[2] - f[2] * u[1], f[2] * u[0] - f[0] * u[2], f[0] * u[1] - f[1] * u[0]};
  if (!(vec3_length(x) > 1e-6)) fail(path + "/up", "is parallel to the view direction (look_at - position)" + at);
}

// Depth of field, shutter and camera motion (docs/scene-format.md, "Lens and time").
void Parser::camera_lens_time(const json& j, const std::string& path, CameraDesc& c) {
  c.aperture_radius = number(j, path, "aperture_radius", 0.0, kNonNegative);
  c.focus_distance = number(j, path, "focus_distance", 0.0, kPositive);
  if (const json* v = find(j, "shutter")) {
    const std::string p = path + "/shutter";
    if (!v->is_array() || v->size() != 2)
      fail(p, std::string("expected [open, close] in seconds, got ") +
                  (v->is_array() ? "an array of " + std::to_string(v->size()) + " values" : v->type_name()));
    const std::array<double, 2> sh{number_at((*v)[0], p + "/0", kFloat), number_at((*v)[1], p + "/1", kFloat)};
    if (!(sh[1] >= sh[0])) fail(p, "close " + num(sh[1]) + " is before open " + num(sh[0]));
    if (!kFloat.holds(sh[1] - sh[0])) fail(p, "its length " + num(sh[1] - sh[0]) + " is not finite as a float");
    c.shutter = sh;
  }
  if (find(j, "position_close")) c.position_close = vec3(j, path, "position_close", c.position, kAny);
  if (find(j, "look_at_close")) c.look_at_close = vec3(j, path, "look_at_close", c.look_at, kAny);
  const char* moving = c.position_close ? "/position_close" : "/look_at_close";
  if ((c.position_close || c.look_at_close) && (c.position_auto || c.look_at_media || c.fit > 0))
    fail(path + moving, "camera motion needs a position and look_at given as points and no fit (no framing: a framed "
                        "position would move the camera's path away from the one written)");
}

// Framing (docs/scene-format.md, scene/framing.h): "look_at": "media", "position": "auto", "fit".
void Parser::camera_framing(const json& j, const std::string& path, CameraDesc& c) {
  if (const json* v = find(j, "look_at"); v && v->is_string()) {
    if (v->get<std::string>() != "media")
      fail(path + "/look_at", "expected a point [x, y, z] or \"media\", got " + in_quotes(v->get<std::string>()));
    c.look_at_media = true;
  }
  if (const json* v = find(j, "position"); v && v->is_string()) {
    if (v->get<std::string>() != "auto")
      fail(path + "/position", "expected a point [x, y, z] or \"auto\", got " + in_quotes(v->get<std::string>()));
    c.position_auto = true;
  }
  if (find(j, "fit")) {
    c.fit = number(j, path, "fit", 1.0, Range{0, 1000, true, false});
  } else if (c.position_auto) {
    c.fit = 1.1;
  }
  if (c.position_auto && !c.look_at_media && !find(j, "look_at"))
    c.look_at_media = true;  // "auto" alone: aim at the media too
}

void Parser::film(const json& j, const std::string& path, FilmDesc& f) {
  expect_object(j, path);
  fields(j, path, {"width", "height", "spp", "output", "alpha", "aovs", "half", "compression"});
  f.width = static_cast<int>(integer(j, path, "width", f.width, 1, 65536));
  f.height = static_cast<int>(integer(j, path, "height", f.height, 1, 65536));
  if (static_cast<long long>(f.width) * f.height > (1ll << 28))
    fail(path, "width * height = " + std::to_string(static_cast<long long>(f.width) * f.height) +
                   " pixels is too many (at most 2^28)");
  const OptionCheck& spp = option_row("spp").check;  // the range of --spp (integrator/option_table.def)
  f.spp = static_cast<int>(integer(j, path, "spp", f.spp, int64_t(spp.lo), int64_t(spp.hi)));
  auto boolean = [&](const char* key) -> std::optional<bool> {
    const json* v = find(j, key);
    if (!v) return std::nullopt;
    if (!v->is_boolean()) fail(path + "/" + key, std::string("expected true or false, got ") + v->type_name());
    return v->get<bool>();
  };
  f.alpha = boolean("alpha");
  f.half = boolean("half").value_or(false);
  if (const json* a = find(j, "aovs")) {
    if (!a->is_array()) fail(path + "/aovs", std::string("expected an array of layer names, got ") + a->type_name());
    for (size_t i = 0; i < a->size(); ++i) {
      const json& v = (*a)[i];
      const std::string at = child(path + "/aovs", i);
      if (!v.is_string()) fail(at, std::string("expected a layer name, got ") + v.type_name());
      const int k = aov_from_name(v.get<std::string>());
      if (k < 0) fail(at, "unknown layer " + in_quotes(v.get<std::string>()) + " (expected one of: " + aov_names() + ")");
      f.aovs |= 1u << k;
    }
    if ((f.aovs & ST_AOV_BIT(ALPHA)) && f.alpha == false)
      fail(path + "/aovs", "lists \"alpha\" but film.alpha is false");
    if (f.aovs & ST_AOV_BIT(ALPHA)) f.alpha = true;
  }
  if (find(j, "compression")) {
    f.compression = string(j, path, "compression", "");
    const auto& names = exr_compressions();
    if (std::find(names.begin(), names.end(), f.compression) == names.end()) {
      std::string list;
      for (auto& n : names) list += (list.empty() ? "" : ", ") + n;
      fail(path + "/compression", "unknown EXR compression " + in_quotes(f.compression) + " (expected one of: " + list + ")");
    }
  }
  if (!find(j, "output")) {
    f.output = normalized(dir_ / f.output).string();
    return;
  }
  f.output = file(j, path, "output", false);
  std::string ext = lower_extension(f.output);
  if (ext != ".exr" && ext != ".png")
    fail(path + "/output", "unsupported image type " + in_quotes(ext) + " (expected .exr or .png)");
}

void Parser::render(const json& j, const std::string& path, RenderDesc& r) {
  expect_object(j, path);
  fields(j, path,
         {"tracker", "spectral_scheme", "absorption", "light_sampling", "transmittance", "lookup", "color", "max_depth", "seed",
          "time_limit", "guiding", "noise_target", "adaptive", "equiangular", "wavelength_sampling"});
  // a name from one of the enum tables of kernels/types.h (scene/names.cpp): its value, or the
  // field named with the valid names
  auto named = [&](const char* key, const char* what, int (*from_name)(const std::string&), std::string (*names)(),
                   auto* out) {
    if (!find(j, key)) return false;
    std::string t = string(j, path, key, "");
    const int v = from_name(t);
    if (v < 0)
      fail(path + "/" + key, std::string("unknown ") + what + " " + in_quotes(t) + " (expected one of: " + names() + ")");
    using Out = std::remove_pointer_t<decltype(out)>;
    if constexpr (std::is_enum_v<Out>)
      *out = Out(v);
    else
      *out = typename Out::value_type(v);
    return true;
  };
  named("tracker", "tracker", tracker_from_name, tracker_names, &r.tracker);
  r.scheme_set = named("spectral_scheme", "spectral scheme", scheme_from_name, scheme_names, &r.scheme) || r.scheme_set;
  named("absorption", "absorption mode", absorption_from_name, absorption_names, &r.absorption);
  named("light_sampling", "light sampling", light_sampling_from_name, light_sampling_names, &r.light_sampling);
  named("transmittance", "transmittance estimator", transmittance_from_name, transmittance_names, &r.transmittance);
  named("lookup", "density lookup mode", lookup_from_name, lookup_names, &r.lookup);
  named("color", "colour mode", film_color_from_name, film_color_names, &r.color);
  named("wavelength_sampling", "wavelength sampling", wavelength_sampling_from_name, wavelength_sampling_names,
        &r.wavelength_sampling);
  named("guiding", "guiding mode", guiding_from_name, guiding_names, &r.guiding);
  named("equiangular", "equi-angular mode", guiding_from_name, guiding_names, &r.equiangular);
  // -1: unlimited, as the kernels read it (types.h st_scene.max_depth)
  if (find(j, "max_depth")) {
    const int d = static_cast<int>(integer(j, path, "max_depth", -1, -1, std::numeric_limits<int>::max()));
    r.max_depth = d >= 0 ? std::optional<int>(d) : std::nullopt;
  }
  const OptionCheck& seed = option_row("seed").check;  // the range of --seed
  r.seed = static_cast<uint32_t>(integer(j, path, "seed", r.seed, int64_t(seed.lo), int64_t(seed.hi)));
  // the range of the option that overrides the field (--time-limit, --noise-target)
  for (const auto& [key, out] : {std::pair{"time_limit", &r.time_limit}, std::pair{"noise_target", &r.noise_target}})
    if (find(j, key)) {
      const OptionCheck& c = option_row(key).check;
      *out = number(j, path, key, 0.0, Range{c.lo, c.hi, false, false});
    }
  if (const json* v = find(j, "adaptive")) {
    if (!v->is_boolean()) fail(path + "/adaptive", std::string("expected true or false, got ") + v->type_name());
    r.adaptive = v->get<bool>();
  }
}

// nlohmann's messages start with "[json.exception.parse_error.101] "; keep what follows.
std::string library_reason(const std::exception& e) {
  std::string w = e.what();
  size_t k = w.find("] ");
  return k == std::string::npos ? w : w.substr(k + 2);
}

}  // namespace parsing


using namespace parsing;

SceneDesc parse_scene(const std::string& json_text, const std::string& name, const std::string& dir) {
  // Duplicate keys: a stack of open containers gives the JSON path of the repeated key.
  struct Open {
    bool object;
    std::set<std::string> keys;
    std::string key;
    size_t index = 0;
  };
  std::vector<Open> open;
  auto callback = [&](int, json::parse_event_t event, json& parsed) {
    using E = json::parse_event_t;
    if (event == E::object_start || event == E::array_start) {
      open.push_back({event == E::object_start, {}, {}, 0});
    } else if (event == E::key) {
      std::string key = parsed.get<std::string>();
      if (!open.back().keys.insert(key).second) {
        std::string path;
        for (size_t i = 0; i + 1 < open.size(); ++i)
          path = open[i].object ? child(path, open[i].key) : child(path, open[i].index);
        throw Error(name + ": " + child(path, key) + ": duplicate field");
      }
      open.back().key = key;
    } else {
      if (event == E::object_end || event == E::array_end) open.pop_back();
      if (!open.empty() && !open.back().object) open.back().index++;
    }
    return true;
  };

  // nlohmann 3.11 with a parse callback rescans a container after each of its elements, which is
  // quadratic in array length; a scene has a few dozen objects, so absurd counts are refused first
  const size_t objects = size_t(std::count(json_text.begin(), json_text.end(), '{'));
  if (objects > 4096)
    throw Error(name + ": " + std::to_string(objects) + " JSON objects; a scene has at most " +
                std::to_string(ST_MAX_MEDIA) + " media and " + std::to_string(ST_MAX_LIGHTS) +
                " lights, refusing to parse");
  json root;
  try {
    root = json::parse(json_text, callback);
  } catch (const json::out_of_range& e) {
    // Number overflow (1e999), the only range error of the text parser, comes without a
    // position: locate the quoted literal in the text.
    std::string reason = library_reason(e), where;
    size_t q0 = reason.find('\''), q1 = reason.rfind('\'');
    size_t at = q0 < q1 ? json_text.find(reason.substr(q0 + 1, q1 - q0 - 1)) : std::string::npos;
    if (at != std::string::npos) {
      size_t line_start = json_text.rfind('\n', at) + 1;  // npos + 1 == 0 on the first line
      where = "line " + std::to_string(1 + std::count(json_text.begin(), json_text.begin() + at, '\n')) +
              ", column " + std::to_string(at - line_start + 1) + ": ";
    }
    throw Error(name + ": " + where + reason + " (numbers must be finite)");
  } catch (const json::exception& e) {
    throw Error(name + ": " + library_reason(e));
  }
  Parser parser(name, dir);
  SceneDesc s = parser.scene(root);
  s.path = name;
  check_radiance_bounds(s);  // magnitudes the float kernels cannot carry (scene/radiance.h)
  return s;
}

std::string read_scene_text(const std::string& path) {
  // The common failures keep their plain wording; anything else that is not a regular file of at
  // most kMaxSceneBytes (a FIFO, /dev/zero, a huge file) is refused by read_input_file.
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  if (!fs::exists(st))
    throw Error(path + ": cannot open scene file (" + (ec ? ec.message() : "No such file or directory") + ")");
  if (fs::is_directory(st)) throw Error(path + ": cannot open scene file (Is a directory)");
  const std::string ext = lower_extension(path);
  if (ext == ".usd" || ext == ".usda" || ext == ".usdc" || ext == ".usdz")
    throw Error(path + ": is a USD stage; a scene file is spectrack's JSON: convert the stage with `python3 -m "
                "spectrack.usd2scene " + path + " -o scene.json`, or load it in Python with spectrack.load_usd "
                "(docs/usd.md)");
  return read_input_file(path, "", kMaxSceneBytes);
}

SceneDesc load_scene(const std::string& path) {
  const std::string text = read_scene_text(path);
  fs::path dir = fs::path(path).parent_path();
  return parse_scene(text, path, dir.empty() ? "." : dir.string());
}

}  // namespace spectrack
