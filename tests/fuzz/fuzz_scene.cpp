// fuzz_scene.cpp: libFuzzer harness for the scene loader (src/scene). Built only with
// -DSPECTRACK_FUZZ=ON and clang (-fsanitize=fuzzer,address,undefined); scripts/fuzz.sh builds and
// runs it on a copy of tests/fuzz/corpus/.
//
// Contract under test ("never crash, never lie"): parse_scene() either returns a scene that obeys
// the documented ranges or throws spectrack::Error whose message starts with the scene's name.
// Anything else is a finding and aborts: another exception type (std::terminate), a sanitizer
// report, a timeout, or a violated check below.
//
// Scenes name files: those are resolved against a scratch folder made once per process under
// $TMPDIR (removed at exit) holding the names the seeds use (cloud.vdb, env.exr, ../volumes/...),
// so the fuzzer also reaches the fields read after a file check. Missing files are plain errors.
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <string>
#include <system_error>

#include "scene/radiance.h"
#include "scene/scene.h"
#include "fuzz_contract.h"

namespace {

namespace fs = std::filesystem;
constexpr const char* kName = "fuzz.json";

fs::path g_root;       // removed at exit
std::string g_dir;     // the scene folder given to parse_scene

void remove_root() {
  std::error_code ec;
  if (!g_root.empty()) fs::remove_all(g_root, ec);
}

bool finite3(const spectrack::Vec3& v) { return std::isfinite(v[0]) && std::isfinite(v[1]) && std::isfinite(v[2]); }
bool nonneg3(const spectrack::Vec3& v) { return finite3(v) && v[0] >= 0 && v[1] >= 0 && v[2] >= 0; }

// The documented meaning of an accepted scene (scene.h, docs/scene-format.md, kernels/types.h).
void check_scene(const spectrack::SceneDesc& s) {
  using namespace spectrack;
  check(s.path == kName, "SceneDesc::path is not the given name");
  const CameraDesc& c = s.camera;
  check(c.type == ST_CAMERA_PERSPECTIVE || c.type == ST_CAMERA_ORTHOGRAPHIC, "camera type");
  check(finite3(c.position) && finite3(c.look_at) && finite3(c.up), "camera vectors not finite");
  check(c.fov_deg > 0 && c.fov_deg < 180, "camera fov_deg out of (0, 180)");
  check(std::isfinite(c.height) && c.height > 0, "camera height not positive");
  // framing ("look_at": "media", "position": "auto") resolves the view direction at packing time
  check(c.look_at_media || c.position_auto || c.position != c.look_at, "camera look_at equals position");
  check(c.fit == 0 || (c.fit > 0 && c.fit <= 1000), "camera fit out of (0, 1000]");
  check(s.film.width >= 1 && s.film.width <= 65536 && s.film.height >= 1 && s.film.height <= 65536, "film size");
  check(static_cast<long long>(s.film.width) * s.film.height <= (1ll << 28), "film has more than 2^28 pixels");
  check(s.film.spp >= 1 && s.film.spp <= (1 << 24), "film spp");
  check(fs::path(s.film.output).is_absolute(), "film output not resolved to an absolute path");
  check(s.render.tracker >= 0 && s.render.tracker < ST_TRACKER_COUNT, "render tracker");
  check(s.render.scheme >= 0 && s.render.scheme < ST_SCHEME_COUNT, "render scheme");
  check(!s.render.max_depth || *s.render.max_depth >= 0, "render max_depth < 0");
  check(s.lights.size() <= ST_MAX_LIGHTS, "more than ST_MAX_LIGHTS lights");
  int environments = 0;
  for (const LightDesc& l : s.lights) {
    check(l.type >= ST_LIGHT_ENV_UNIFORM && l.type <= ST_LIGHT_SPHERE, "light type");
    const bool local = l.type == ST_LIGHT_POINT || l.type == ST_LIGHT_SPOT || l.type == ST_LIGHT_SPHERE;
    if (l.type == ST_LIGHT_ENV_UNIFORM || l.type == ST_LIGHT_ENV_MAP) ++environments;
    if (local) check(finite3(l.position) && nonneg3(l.intensity), "local light position or intensity");
    if (l.type == ST_LIGHT_SPOT)
      check(l.cone_angle_deg > 0 && l.cone_angle_deg <= 180 && l.cone_delta_deg >= 0 && l.cone_delta_deg <= l.cone_angle_deg,
            "spot cone");
    if (l.type == ST_LIGHT_SPHERE) check(l.radius > 0 && std::isfinite(l.radius), "sphere radius");
    check(nonneg3(l.radiance) && nonneg3(l.irradiance), "light radiance/irradiance negative or not finite");
    check(std::isfinite(l.scale) && l.scale >= 0, "light scale");
    check(finite3(l.to_light) && (l.to_light[0] != 0 || l.to_light[1] != 0 || l.to_light[2] != 0), "light to_light");
    check(l.angle_deg >= 0 && l.angle_deg < 180, "light angle_deg");
    check(l.type != ST_LIGHT_ENV_MAP || l.sky || fs::path(l.map).is_absolute(), "environment map not absolute");
    // scene/radiance.h: what the float kernels can carry
    const double r = std::max({l.radiance[0], l.radiance[1], l.radiance[2]});
    const double e = std::max({l.irradiance[0], l.irradiance[1], l.irradiance[2]});
    if (l.type == ST_LIGHT_ENV_UNIFORM) check(4.0 * M_PI * r <= kMaxRadiance, "uniform environment over the radiance bound");
    if (l.type == ST_LIGHT_ENV_MAP) check(l.scale <= kMaxRadiance, "map scale over the radiance bound");
    if (l.type == ST_LIGHT_DIRECTIONAL && l.angle_deg == 0) check(e / (4.0 * M_PI) <= kMaxRadiance, "delta sun over the bound");
    if (l.type == ST_LIGHT_DIRECTIONAL && l.angle_deg > 0) {
      const double h = l.angle_deg * M_PI / 360.0;
      check(e / (M_PI * std::sin(h) * std::sin(h)) <= kMaxRadiance * (1 + 1e-9), "sun disc radiance over the bound");
    }
  }
  check(environments <= 1, "more than one environment light");
  check(s.media.size() <= ST_MAX_MEDIA, "more than ST_MAX_MEDIA media");
  std::set<std::string> names;
  for (const MediumDesc& m : s.media) {
    check(names.insert(m.name).second, "duplicate medium name accepted");
    check(m.type == ST_MEDIUM_VDB || m.type == ST_MEDIUM_HOMOGENEOUS, "medium type");
    check(std::isfinite(m.density_scale) && m.density_scale >= 0, "medium density_scale");
    check(nonneg3(m.sigma_s) && nonneg3(m.sigma_a), "medium sigma negative or not finite");
    check(m.phase.type == ST_PHASE_ISOTROPIC || m.phase.type == ST_PHASE_HG, "phase type");
    check(m.phase.g > -1 && m.phase.g < 1, "phase g out of (-1, 1)");
    check(std::abs(float(m.phase.g)) < 1.0f, "phase g rounds to +-1 in float");
    if (m.emission.present)
      check(nonneg3(m.emission.radiance) && std::isfinite(m.emission.scale) && m.emission.scale >= 0, "emission");
    check(std::isfinite(m.majorant_scale) && m.majorant_scale > 0, "majorant_scale");
    check(std::isfinite(m.minorant_scale) && m.minorant_scale >= 0, "minorant_scale");
    if (m.type == ST_MEDIUM_VDB) {
      check(fs::path(m.file).is_absolute(), "vdb file not absolute");
      check(m.grid_index >= -1, "grid_index");
      const TransformDesc& t = m.transform;
      check(finite3(t.scale) && finite3(t.rotate_deg) && finite3(t.translate), "transform not finite");
      check(t.scale[0] != 0 && t.scale[1] != 0 && t.scale[2] != 0, "transform scale zero");
    } else {
      for (int a = 0; a < 3; ++a)
        check(std::isfinite(m.bounds[0][a]) && std::isfinite(m.bounds[1][a]) && m.bounds[0][a] < m.bounds[1][a],
              "homogeneous bounds empty or not finite");
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  const char* tmp = std::getenv("TMPDIR");
  g_root = fs::path(tmp && *tmp ? tmp : "/tmp") / ("spectrack-fuzz-" + std::to_string(getpid()));
  const fs::path scenes = g_root / "scenes";
  fs::create_directories(scenes / "folder.vdb");  // a folder where a file is expected
  fs::create_directories(g_root / "volumes");
  for (const fs::path& f : {scenes / "cloud.vdb", scenes / "smoke.nvdb", scenes / "env.exr", scenes / "sky.hdr",
                            g_root / "volumes" / "cloud.vdb"})
    std::ofstream(f) << "not really a volume\n";
  g_dir = scenes.string();
  std::atexit(remove_root);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    spectrack::SceneDesc scene = spectrack::parse_scene(text, kName, g_dir);
    check_scene(scene);
  } catch (const spectrack::Error& e) {
    // An error must name the scene file first ("fuzz.json: /media/0/sigma_s: ...").
    const std::string msg = e.what();
    if (msg.compare(0, std::char_traits<char>::length(kName) + 2, std::string(kName) + ": ") != 0)
      finding("error message does not start with the scene name: " + msg);
  }
  return 0;
}
