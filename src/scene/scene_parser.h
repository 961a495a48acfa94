// scene_parser.h: the scene loader's Parser and its helpers, shared by scene.cpp (the file, camera,
// film and render sections) and scene_media.cpp (media, their phase, emission, colour and
// transform, and lights). Internal to src/scene: parse_scene and load_scene (scene.h) are the
// interface. Every failure goes through Parser::fail: "<scene>: <json path>: <reason>".
#pragma once
#include <filesystem>
#include <iomanip>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "scene/scene.h"
#include "scene/frames.h"
#include "util/error.h"
#include "util/files.h"

namespace spectrack {
namespace parsing {

using json = nlohmann::json;
namespace fs = std::filesystem;
using Names = std::vector<const char*>;

inline constexpr const char* kFormat = "spectrack-scene/1";
inline constexpr double kInf = std::numeric_limits<double>::infinity();

inline std::string num(double v) {
  std::ostringstream s;
  s << std::setprecision(12) << v;
  return s.str();
}

inline std::string join(const Names& names) {
  std::string s;
  for (const char* n : names) s += (s.empty() ? "" : ", ") + std::string(n);
  return s;
}

inline bool contains(const Names& names, const std::string& key) {
  for (const char* n : names)
    if (key == n) return true;
  return false;
}

// A JSON pointer (RFC 6901) step: "~" and "/" inside keys are escaped.
inline std::string child(const std::string& path, const std::string& key) {
  std::string s = path + "/";
  for (char c : key) s += c == '~' ? "~0" : c == '/' ? "~1" : std::string(1, c);
  return s;
}
inline std::string child(const std::string& path, size_t index) { return path + "/" + std::to_string(index); }

inline std::string in_quotes(const std::string& s) { return "\"" + s + "\""; }

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
inline const Range kAny{-kInf, kInf, true, true};
// A value the kernels hold as a float (a shutter time): finite as a float.
inline const Range kFloat{-3.4028234663852886e38, 3.4028234663852886e38, false, false};
inline const Range kNonNegative{0, kInf, false, true};
inline const Range kPositive{0, kInf, true, true};

inline fs::path normalized(const fs::path& p) {
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
  void camera_lens_time(const json& j, const std::string& path, CameraDesc& c);
  void check_view(const std::string& path, const std::string& at, const Vec3& position, const Vec3& look_at,
                  const Vec3& up);
  void film(const json& j, const std::string& path, FilmDesc& f);
  void render(const json& j, const std::string& path, RenderDesc& r);
  LightDesc light(const json& j, const std::string& path);
  GroundDesc ground(const json& j, const std::string& path);
  void local_light(const json& j, const std::string& path, bool spot, const Names& all, LightDesc& l);
  void sky_light(const json& j, const std::string& path, const Names& all, LightDesc& l);
  MediumDesc medium(const json& j, const std::string& path, size_t index);
  PhaseDesc phase(const json& j, const std::string& path);
  EmissionDesc ramp(const json& j, const std::string& path, bool vdb, EmissionDesc e);
  EmissionDesc emission(const json& j, const std::string& path, bool vdb);
  ColorDesc color(const json& j, const std::string& path);
  VelocityDesc velocity(const json& j, const std::string& path);
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
  // Resolves `key` (a path string) against the scene folder; `must_exist` for input files. A missing
  // file's error quotes the object's "<key>_source" string when it has one: where to get a
  // third-party file that the repository does not hold.
  std::string file(const json& obj, const std::string& path, const char* key, bool must_exist) const {
    std::string p = string(obj, path, key, "");
    fs::path resolved = normalized(fs::path(p).is_absolute() ? fs::path(p) : dir_ / p);
    std::error_code ec;
    if (must_exist && has_frame_pattern(resolved.filename().string())) return resolved.string();  // checked per frame (--frames)
    if (must_exist && !fs::exists(resolved, ec)) {
      const std::string source = string(obj, path, (std::string(key) + "_source").c_str(), "");
      fail(child(path, key), resolved.string() + ": no such file" +
                                 (source.empty() ? "" : "; it is third-party data, not in the repository: " + source));
    }
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

}  // namespace parsing
}  // namespace spectrack
