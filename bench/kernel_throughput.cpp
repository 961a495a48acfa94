// kernel_throughput: the renderer's device functions in isolation on one OpenCL device.
//
//   kernel_throughput SCENE.json [--device D] [--points N] [--paths N] [--medium I] [--json FILE]
//
// Design: every figure runs the renderer's own kernels through Renderer's probe_* entry points, so
// nothing here re-implements tracking. (1) Kernel build: construction time (VDB load, majorant
// grid, program build from source or from the on-disk cache) and the first and second tiny
// renders (16x16, 1 spp): the difference is the driver's first-launch cost (PoCL compiles the
// work-group functions of each kernel at first launch). Run it once with an empty
// SPECTRACK_KERNEL_CACHE_DIR (and POCL_KERNEL_CACHE=0) for the cold figure and again for the warm
// one. (2) Density lookups/s: N points uniform in the world box of the active voxels, one
// trilinear NanoVDB lookup each (k_probe_density). (3) DDA cell steps/s: free-path sampling along
// the camera's central ray through a copy of the medium with density_scale 1e-9, so T_maj is ~1
// everywhere and the walk is nothing but majorant-grid cell steps. (4) Tracked free paths/s per
// tracker: N free paths from the camera along its central ray (k_probe_track), each to its first
// real collision or escape, with the density lookups and DDA steps they did. Times are host wall
// clock around one probe call (upload, launch, read-back), the best of 3 after a warm-up call.
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <string>

#include "render/renderer.h"
#include "scene/scene.h"
#include "util/error.h"
#include "volume/volume.h"

using namespace spectrack;

namespace {

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

int usage() {
  std::cerr << "usage: kernel_throughput SCENE.json [--device D] [--points N] [--paths N] [--medium I] [--json FILE]\n";
  return 2;
}

// Scene transform: scale, then rotations about x, y, z, then translate (SCENE_FORMAT.md).
std::array<double, 3> apply_transform(const TransformDesc& t, std::array<double, 3> p) {
  for (int a = 0; a < 3; ++a) p[a] *= t.scale[a];
  for (int axis = 0; axis < 3; ++axis) {
    const double r = t.rotate_deg[axis] * M_PI / 180.0, c = std::cos(r), s = std::sin(r);
    const int i = (axis + 1) % 3, j = (axis + 2) % 3;
    const double pi = c * p[i] - s * p[j], pj = s * p[i] + c * p[j];
    p[i] = pi, p[j] = pj;
  }
  for (int a = 0; a < 3; ++a) p[a] += t.translate[a];
  return p;
}

// Best of 3 timed calls after one warm-up call.
template <typename F>
double best_time(F&& f) {
  f();
  double best = 1e30;
  for (int i = 0; i < 3; ++i) {
    auto t = Clock::now();
    f();
    best = std::min(best, since(t));
  }
  return best;
}

std::array<float, 3> unit(std::array<double, 3> v) {
  const double n = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
  return {float(v[0] / n), float(v[1] / n), float(v[2] / n)};
}

}  // namespace

int main(int argc, char** argv) {
  std::string scene_path, device, json_path;
  long n_points = 1 << 20, n_paths = 1 << 16;
  int medium = 0;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next_long = [&](long lo, long hi, long* v) {
      if (i + 1 >= argc) return false;
      char* end = nullptr;
      *v = std::strtol(argv[++i], &end, 10);
      return *end == '\0' && *v >= lo && *v <= hi;
    };
    long v = 0;
    if (a == "--device" && i + 1 < argc) device = argv[++i];
    else if (a == "--json" && i + 1 < argc) json_path = argv[++i];
    else if (a == "--points") { if (!next_long(1, 1L << 26, &n_points)) return usage(); }
    else if (a == "--paths") { if (!next_long(1, 1L << 24, &n_paths)) return usage(); }
    else if (a == "--medium") { if (!next_long(0, 63, &v)) return usage(); medium = int(v); }
    else if (scene_path.empty() && !a.empty() && a[0] != '-') scene_path = a;
    else return usage();
  }
  if (scene_path.empty()) return usage();

  try {
    SceneDesc scene = load_scene(scene_path);
    if (medium >= int(scene.media.size()) || scene.media[size_t(medium)].type != ST_MEDIUM_VDB)
      throw Error(fmt::format("{}: medium {} is not a VDB medium", scene_path, medium));
    const MediumDesc& m = scene.media[size_t(medium)];
    scene.film.width = 16, scene.film.height = 16, scene.film.spp = 1;
    RenderOptions opt;
    opt.device = device;
    opt.quiet = true;
    nlohmann::json j;
    j["scene"] = scene_path;

    // (1) Set-up, program build and first launches.
    auto t0 = Clock::now();
    Renderer r(scene, opt);
    const double t_construct = since(t0);
    t0 = Clock::now();
    RenderResult first = r.render();
    const double t_first = since(t0);
    t0 = Clock::now();
    r.render();
    const double t_second = since(t0);
    j["device"] = r.device_name();
    j["kernels_from_cache"] = first.kernels_from_cache;
    j["seconds_construct"] = t_construct;
    j["seconds_program_build"] = first.seconds_build;
    j["seconds_first_render"] = t_first;
    j["seconds_second_render"] = t_second;
    j["seconds_kernel_build_total"] = first.seconds_build + std::max(0.0, t_first - t_second);

    // (2) Density lookups at uniform points of the active box, in world space.
    GridData g = load_float_grid(m.file, m.grid, m.grid_index, scene_path);
    std::vector<std::array<float, 3>> pts(static_cast<size_t>(n_points));
    uint64_t h = 0x9e3779b97f4a7c15ull;
    auto u01 = [&] {
      h ^= h << 13, h ^= h >> 7, h ^= h << 17;
      return double(h >> 11) * (1.0 / 9007199254740992.0);
    };
    for (auto& p : pts) {
      std::array<double, 3> ip, wp{};
      for (int a = 0; a < 3; ++a) ip[a] = g.index_min[a] - 1 + u01() * (g.index_max[a] - g.index_min[a] + 2);
      for (int a = 0; a < 3; ++a)
        wp[a] = g.index_to_world[a][0] * ip[0] + g.index_to_world[a][1] * ip[1] + g.index_to_world[a][2] * ip[2] +
                g.index_to_world[a][3];
      wp = apply_transform(m.transform, wp);
      p = {float(wp[0]), float(wp[1]), float(wp[2])};
    }
    double sum = 0;
    const double t_density = best_time([&] {
      auto d = r.probe_density(medium, pts);
      sum = 0;
      for (float x : d) sum += x;
    });
    j["density"] = {{"points", n_points}, {"seconds", t_density}, {"lookups_per_second", double(n_points) / t_density},
                    {"mean_density", sum / double(n_points)}};

    // The camera's central ray.
    const auto& c = scene.camera;
    const std::array<float, 3> o{float(c.position[0]), float(c.position[1]), float(c.position[2])};
    const std::array<float, 3> dir =
        unit({c.look_at[0] - c.position[0], c.look_at[1] - c.position[1], c.look_at[2] - c.position[2]});
    auto track = [&](Renderer& rr, int channel) {
      double lookups = 0, steps = 0, escaped = 0;
      const double t = best_time([&] {
        auto out = rr.probe_track(o, dir, channel, int(n_paths));
        lookups = steps = escaped = 0;
        for (auto& e : out) lookups += e[2], steps += e[3], escaped += std::isinf(e[0]) ? 1 : 0;
      });
      return nlohmann::json{{"paths", n_paths},
                            {"seconds", t},
                            {"paths_per_second", double(n_paths) / t},
                            {"lookups_per_path", lookups / double(n_paths)},
                            {"dda_steps_per_path", steps / double(n_paths)},
                            {"lookups_per_second", lookups / t},
                            {"dda_steps_per_second", steps / t},
                            {"escaped_fraction", escaped / double(n_paths)}};
    };

    // (3) DDA steps in isolation: the same grid with a vanishing density scale.
    {
      SceneDesc thin = scene;
      thin.media[size_t(medium)].density_scale *= 1e-9;
      Renderer rt(thin, opt);
      j["dda"] = track(rt, 0);
    }

    // (4) Tracked free paths per tracker.
    const std::vector<std::string> trackers = {"delta-per-channel", "spectral", "decomposition", "spectral-decomposition"};
    for (const auto& name : trackers) {
      RenderOptions o2 = opt;
      o2.tracker = tracker_from_name(name);
      Renderer rr(scene, o2);
      const bool per_channel = name == "delta-per-channel" || name == "decomposition";
      j["track"][name] = track(rr, per_channel ? 0 : -1);
    }

    std::cout << fmt::format("device: {}\n", j["device"].get<std::string>());
    std::cout << fmt::format("kernel build: program {:.2f} s ({}), first launches +{:.2f} s, total {:.2f} s\n",
                             first.seconds_build, first.kernels_from_cache ? "from cache" : "compiled",
                             std::max(0.0, t_first - t_second), j["seconds_kernel_build_total"].get<double>());
    std::cout << fmt::format("density lookups: {:.3g}/s ({} points)\n", double(n_points) / t_density, n_points);
    std::cout << fmt::format("DDA cell steps (empty walk): {:.3g}/s ({:.1f} steps/path)\n",
                             j["dda"]["dda_steps_per_second"].get<double>(), j["dda"]["dda_steps_per_path"].get<double>());
    for (const auto& name : trackers) {
      const auto& t = j["track"][name];
      std::cout << fmt::format("{:<24} free paths {:.3g}/s, {:.2f} lookups/path, {:.2f} DDA steps/path, lookups {:.3g}/s\n",
                               name, t["paths_per_second"].get<double>(), t["lookups_per_path"].get<double>(),
                               t["dda_steps_per_path"].get<double>(), t["lookups_per_second"].get<double>());
    }
    if (!json_path.empty()) {
      std::ofstream f(json_path);
      if (!f) throw Error("cannot write " + json_path);
      f << j.dump(2) << "\n";
    }
  } catch (const std::exception& e) {
    std::cerr << "kernel_throughput: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
