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
#include <map>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>

#include "scene/scene.h"
#include "scene/phase_models.h"
#include "scene/presets.h"
#include "scene/radiance.h"
#include "util/files.h"
#include "scene/frames.h"

namespace spectrack {
namespace {

using json = nlohmann::json;
namespace fs = std::filesystem;
using Names = std::vector<const char*>;

constexpr const char* kFormat = "spectrack-scene/1";
constexpr double kInf = std::numeric_limits<double>::infinity();

std::string num(double v) {
  std::ostringstream s;
  s << std::setprecision(12) << v;
  return s.str();
}

std::string join(const Names& names) {
  std::string s;
  for (const char* n : names) s += (s.empty() ? "" : ", ") + std::string(n);
  return s;
}

bool contains(const Names& names, const std::string& key) {
  for (const char* n : names)
    if (key == n) return true;
  return false;
}

// A JSON pointer (RFC 6901) step: "~" and "/" inside keys are escaped.
std::string child(const std::string& path, const std::string& key) {
  std::string s = path + "/";
  for (char c : key) s += c == '~' ? "~0" : c == '/' ? "~1" : std::string(1, c);
  return s;
}
std::string child(const std::string& path, size_t index) { return path + "/" + std::to_string(index); }

std::string in_quotes(const std::string& s) { return "\"" + s + "\""; }

// A closed or open interval for number checks; the message says which bound was broken.
struct Range {
  double lo, hi;
  bool lo_open, hi_open;
  bool holds(double v) const {
    return (lo_open ? v > lo : v >= lo) && (hi_open ? v < hi : v <= hi);
  }
  std::string describe() const {
    if (hi == kInf) return std::string(lo_open ? "> " : ">= ") + num(lo);
    return "in " + std::string(lo_open ? "(" : "[") + num(lo) + ", " + num(hi) + (hi_open ? ")" : "]");
  }
};
const Range kAny{-kInf, kInf, true, true};
const Range kNonNegative{0, kInf, false, true};
const Range kPositive{0, kInf, true, true};

fs::path normalized(const fs::path& p) {
  fs::path q = fs::absolute(p).lexically_normal();
  // "/a/b/." normalises to "/a/b/": drop the empty last element.
  if (!q.has_filename() && q != q.root_path()) q = q.parent_path();
  return q;
}

class Parser {
 public:
  Parser(std::string name, const std::string& dir)
      : name_(std::move(name)), dir_(normalized(dir.empty() ? fs::path(".") : fs::path(dir))) {}

  SceneDesc scene(const json& root);

 private:
  void camera(const json& j, const std::string& path, CameraDesc& c);
  void camera_framing(const json& j, const std::string& path, CameraDesc& c);
  void film(const json& j, const std::string& path, FilmDesc& f);
  void render(const json& j, const std::string& path, RenderDesc& r);
  LightDesc light(const json& j, const std::string& path);
  MediumDesc medium(const json& j, const std::string& path, size_t index);
  PhaseDesc phase(const json& j, const std::string& path);
  EmissionDesc ramp(const json& j, const std::string& path, bool vdb, EmissionDesc e);
  EmissionDesc emission(const json& j, const std::string& path, bool vdb);
  ColorDesc color(const json& j, const std::string& path);
  TransformDesc transform(const json& j, const std::string& path);

  [[noreturn]] void fail(const std::string& path, const std::string& reason) const {
    throw Error(name_ + ": " + (path.empty() ? "/" : path) + ": " + reason + context_);
  }
  void expect_object(const json& j, const std::string& path) const {
    if (!j.is_object()) fail(path, std::string("expected an object, got ") + j.type_name());
  }
  // Unknown fields fail; a field listed in `elsewhere` is known but not valid for `what`.
  void fields(const json& obj, const std::string& path, const Names& allowed, const char* what = nullptr,
              const Names& elsewhere = {}) const {
    for (auto it = obj.begin(); it != obj.end(); ++it) {
      if (contains(allowed, it.key())) continue;
      if (what && contains(elsewhere, it.key()))
        fail(child(path, it.key()),
             std::string("field not allowed for ") + what + " (expected one of: " + join(allowed) + ")");
      fail(child(path, it.key()), "unknown field (expected one of: " + join(allowed) + ")");
    }
  }
  static const json* find(const json& obj, const char* key) {
    auto it = obj.find(key);
    return it == obj.end() ? nullptr : &*it;
  }
  const json& need(const json& obj, const std::string& path, const char* key, const std::string& hint = "") const {
    const json* v = find(obj, key);
    if (!v) fail(child(path, key), "missing required field" + (hint.empty() ? "" : " (" + hint + ")"));
    return *v;
  }
  void check_number(double v, const std::string& path, const Range& r) const {
    if (!std::isfinite(v)) fail(path, "value " + num(v) + " is not finite");
    if (r.holds(v)) return;
    if (r.lo == 0 && !r.lo_open && r.hi == kInf) fail(path, "value " + num(v) + " is negative");
    fail(path, "value " + num(v) + " is out of range (must be " + r.describe() + ")");
  }
  double number_at(const json& v, const std::string& path, const Range& r) const {
    if (!v.is_number()) fail(path, std::string("expected a number, got ") + v.type_name());
    double d = v.get<double>();
    check_number(d, path, r);
    return d;
  }
  double number(const json& obj, const std::string& path, const char* key, double def, const Range& r) const {
    const json* v = find(obj, key);
    return v ? number_at(*v, child(path, key), r) : def;
  }
  long long integer(const json& obj, const std::string& path, const char* key, long long def, long long lo,
                    long long hi) const;
  std::string string(const json& obj, const std::string& path, const char* key, const std::string& def) const {
    const json* v = find(obj, key);
    if (!v) return def;
    if (!v->is_string()) fail(child(path, key), std::string("expected a string, got ") + v->type_name());
    if (v->get_ref<const std::string&>().empty()) fail(child(path, key), "must not be empty");
    return v->get<std::string>();
  }
  Vec3 vec3_at(const json& v, const std::string& path, const Range& r) const {
    if (!v.is_array() || v.size() != 3 || !v[0].is_number() || !v[1].is_number() || !v[2].is_number())
      fail(path, std::string("expected an array of 3 numbers, got ") +
                     (v.is_array() ? "an array of " + std::to_string(v.size()) + " values" : v.type_name()));
    Vec3 out;
    for (int i = 0; i < 3; ++i) out[i] = number_at(v[i], path, r);
    return out;
  }
  Vec3 vec3(const json& obj, const std::string& path, const char* key, const Vec3& def, const Range& r) const {
    const json* v = find(obj, key);
    return v ? vec3_at(*v, child(path, key), r) : def;
  }
  // Resolves `key` (a path string) against the scene folder; `must_exist` for input files.
  std::string file(const json& obj, const std::string& path, const char* key, bool must_exist) const {
    std::string p = string(obj, path, key, "");
    fs::path resolved = normalized(fs::path(p).is_absolute() ? fs::path(p) : dir_ / p);
    std::error_code ec;
    if (must_exist && has_frame_pattern(resolved.filename().string())) return resolved.string();  // checked per frame (--frames)
    if (must_exist && !fs::exists(resolved, ec)) fail(child(path, key), resolved.string() + ": no such file");
    if (must_exist && fs::is_directory(resolved, ec)) fail(child(path, key), resolved.string() + ": is a directory");
    if (must_exist) {
      try {
        check_input_file(resolved.string(), "");  // a FIFO or device would block or never end
      } catch (const Error& e) {
        fail(child(path, key), e.what());
      }
    }
    return resolved.string();
  }

  std::string name_;
  fs::path dir_;
  std::string context_;  // appended to messages while inside a medium
};

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
  fields(root, "", {"format", "camera", "film", "render", "lights", "media"});

  SceneDesc s;
  s.dir = dir_.string();
  if (const json* j = find(root, "camera")) camera(*j, "/camera", s.camera);
  if (const json* j = find(root, "film")) film(*j, "/film", s.film);
  else s.film.output = normalized(dir_ / s.film.output).string();
  if (const json* j = find(root, "render")) render(*j, "/render", s.render);

  if (const json* lights = find(root, "lights")) {
    if (!lights->is_array()) fail("/lights", std::string("expected an array, got ") + lights->type_name());
    if (lights->size() > ST_MAX_LIGHTS)
      fail("/lights", std::to_string(lights->size()) + " lights given, at most " + std::to_string(ST_MAX_LIGHTS) +
                          " (ST_MAX_LIGHTS) are supported");
    std::string env_path;
    for (size_t i = 0; i < lights->size(); ++i) {
      std::string path = child("/lights", i);
      s.lights.push_back(light((*lights)[i], path));
      if (s.lights.back().type == ST_LIGHT_DIRECTIONAL) continue;
      if (!env_path.empty())
        fail(path, "only one environment light is allowed (the first is " + env_path + ")");
      env_path = path;
    }
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
  const Names all = {"type", "position", "look_at", "up", "fov_deg", "height", "fit"};
  fields(j, path, all);
  std::string type = string(j, path, "type", "perspective");
  if (type == "perspective") {
    c.type = ST_CAMERA_PERSPECTIVE;
    fields(j, path, {"type", "position", "look_at", "up", "fov_deg", "fit"}, "a perspective camera", all);
    c.fov_deg = number(j, path, "fov_deg", c.fov_deg, Range{0, 180, true, true});
  } else if (type == "orthographic") {
    c.type = ST_CAMERA_ORTHOGRAPHIC;
    fields(j, path, {"type", "position", "look_at", "up", "height", "fit"}, "an orthographic camera", all);
    c.height = number(j, path, "height", c.height, kPositive);
  } else {
    fail(path + "/type", "unknown camera type " + in_quotes(type) + " (expected one of: perspective, orthographic)");
  }
  camera_framing(j, path, c);
  if (!c.position_auto) c.position = vec3(j, path, "position", c.position, kAny);
  if (!c.look_at_media) c.look_at = vec3(j, path, "look_at", c.look_at, kAny);
  c.up = vec3(j, path, "up", c.up, kAny);
  const double ulen = std::sqrt(c.up[0] * c.up[0] + c.up[1] * c.up[1] + c.up[2] * c.up[2]);
  if (c.position_auto || c.look_at_media) {  // the view direction is known once the media are (scene/framing.h)
    if (!(ulen > 0)) fail(path + "/up", "is zero");
    return;
  }
  const Vec3 d{c.look_at[0] - c.position[0], c.look_at[1] - c.position[1], c.look_at[2] - c.position[2]};
  const double dlen = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  if (!(dlen > 0)) fail(path + "/look_at", "equals the camera position (no view direction)");
  const Vec3 x{d[1] * c.up[2] - d[2] * c.up[1], d[2] * c.up[0] - d[0] * c.up[2], d[0] * c.up[1] - d[1] * c.up[0]};
  // |d x up| = |d| |up| sin(angle): parallel (or zero) below a small angle.
  if (!(std::sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]) > 1e-6 * dlen * ulen) || !(ulen > 0))
    fail(path + "/up", "is zero or parallel to the view direction (look_at - position)");
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
  f.spp = static_cast<int>(integer(j, path, "spp", f.spp, 1, 1 << 24));
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
  std::string ext = fs::path(f.output).extension().string();
  for (char& ch : ext) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  if (ext != ".exr" && ext != ".png")
    fail(path + "/output", "unsupported image type " + in_quotes(ext) + " (expected .exr or .png)");
}

void Parser::render(const json& j, const std::string& path, RenderDesc& r) {
  expect_object(j, path);
  fields(j, path,
         {"tracker", "spectral_scheme", "absorption", "light_sampling", "transmittance", "lookup", "color", "max_depth", "seed",
          "time_limit", "guiding"});
  // a name from one of the enum tables of kernels/types.h (scene/names.cpp): its value, or the
  // field named with the valid names
  auto named = [&](const char* key, const char* what, int (*from_name)(const std::string&), std::string (*names)(),
                   int* out) {
    if (!find(j, key)) return false;
    std::string t = string(j, path, key, "");
    *out = from_name(t);
    if (*out < 0)
      fail(path + "/" + key, std::string("unknown ") + what + " " + in_quotes(t) + " (expected one of: " + names() + ")");
    return true;
  };
  named("tracker", "tracker", tracker_from_name, tracker_names, &r.tracker);
  r.scheme_set = named("spectral_scheme", "spectral scheme", scheme_from_name, scheme_names, &r.scheme) || r.scheme_set;
  named("absorption", "absorption mode", absorption_from_name, absorption_names, &r.absorption);
  named("light_sampling", "light sampling", light_sampling_from_name, light_sampling_names, &r.light_sampling);
  named("transmittance", "transmittance estimator", transmittance_from_name, transmittance_names, &r.transmittance);
  named("lookup", "density lookup mode", lookup_from_name, lookup_names, &r.lookup);
  named("color", "colour mode", film_color_from_name, film_color_names, &r.color);
  named("guiding", "guiding mode", guiding_from_name, guiding_names, &r.guiding);
  r.max_depth = static_cast<int>(integer(j, path, "max_depth", r.max_depth, -1, std::numeric_limits<int>::max()));
  r.seed = static_cast<uint32_t>(integer(j, path, "seed", r.seed, 0, 0xffffffffll));
  if (find(j, "time_limit")) r.time_limit = number(j, path, "time_limit", 0.0, Range{0, 1e9, true, false});
}

LightDesc Parser::light(const json& j, const std::string& path) {
  expect_object(j, path);
  const Names all = {"type", "radiance", "map", "scale", "to_light", "irradiance", "angle_deg"};
  fields(j, path, all);
  LightDesc l;
  l.json_path = path;
  need(j, path, "type", "expected \"environment\" or \"directional\"");
  std::string type = string(j, path, "type", "");
  if (type == "environment") {
    fields(j, path, {"type", "radiance", "map", "scale"}, "an environment light", all);
    if (find(j, "map")) {
      if (find(j, "radiance")) fail(path + "/radiance", "not allowed together with \"map\" (use \"scale\")");
      l.type = ST_LIGHT_ENV_MAP;
      l.map = file(j, path, "map", true);
      l.scale = number(j, path, "scale", l.scale, kNonNegative);
    } else {
      if (find(j, "scale")) fail(path + "/scale", "only allowed with \"map\"");
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
  } else {
    fail(path + "/type", "unknown light type " + in_quotes(type) + " (expected one of: environment, directional)");
  }
  return l;
}

MediumDesc Parser::medium(const json& j, const std::string& path, size_t index) {
  expect_object(j, path);
  const Names all = {"name", "type", "file", "grid", "grid_index", "bounds", "density_scale", "sigma_s",
                     "sigma_a", "phase", "emission", "color", "transform", "majorant_scale", "minorant_scale",
                     "preset"};
  Names vdb, homogeneous;
  for (const char* k : all) {
    if (std::strcmp(k, "bounds") != 0) vdb.push_back(k);
    if (!contains({"file", "grid", "grid_index", "transform", "color", "preset"}, k)) homogeneous.push_back(k);
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

// nlohmann's messages start with "[json.exception.parse_error.101] "; keep what follows.
std::string library_reason(const std::exception& e) {
  std::string w = e.what();
  size_t k = w.find("] ");
  return k == std::string::npos ? w : w.substr(k + 2);
}

}  // namespace

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

SceneDesc load_scene(const std::string& path) {
  // The common failures keep their plain wording; anything else that is not a regular file of at
  // most kMaxSceneBytes (a FIFO, /dev/zero, a huge file) is refused by read_input_file.
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  if (!fs::exists(st))
    throw Error(path + ": cannot open scene file (" + (ec ? ec.message() : "No such file or directory") + ")");
  if (fs::is_directory(st)) throw Error(path + ": cannot open scene file (Is a directory)");
  const std::string text = read_input_file(path, "", kMaxSceneBytes);
  fs::path dir = fs::path(path).parent_path();
  return parse_scene(text, path, dir.empty() ? "." : dir.string());
}

}  // namespace spectrack
