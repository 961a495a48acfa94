// kernel_throughput: the renderer's device functions in isolation on one OpenCL device.
//
//   kernel_throughput SCENE.json [--device D] [--points N] [--paths N] [--medium I] [--json FILE]
//
// Design: every figure runs the renderer's own kernels through the test probes (device/probe.h), so
// nothing here re-implements tracking. (1) Kernel build: construction time (VDB load, majorant
// grid, program build from source or from the on-disk cache) and the first and second tiny
// renders (16x16, 1 spp): the difference is the driver's first-launch cost (PoCL compiles the
// work-group functions of each kernel at first launch). Run it once with an empty
// SPECTRACK_KERNEL_CACHE_DIR (and POCL_KERNEL_CACHE=0) for the cold figure and again for the warm
// one. (2) Density lookups/s: N points uniform in the world box of the active voxels, one
// trilinear NanoVDB lookup each (k_probe_density; and one stochastic one-voxel lookup each), and the same lookups on the host with NanoVDB's
// ReadAccessor on 1 and 2 threads (the ratio the kernels are judged by). (3) DDA cell steps/s: free-path sampling along
// the camera's central ray through a copy of the medium with density_scale 1e-9, so T_maj is ~1
// everywhere and the walk is nothing but majorant-grid cell steps. (4) Tracked free paths/s per
// tracker: N free paths from the camera along its central ray (k_probe_track), each to its first
// real collision or escape, with the density lookups and DDA steps they did. (5) Shadow-ray
// transmittance, ratio tracking against ray marching (variance x lookups). Times are host wall
// clock around one probe call (upload, launch, read-back), the best of 3 after a warm-up call.
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <future>
#include <iostream>
#include <string>
#include <vector>

#include <nanovdb/NanoVDB.h>

#include "device/probe.h"
#include "integrator/renderer.h"
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

// Scene transform: scale, then rotations about x, y, z, then translate (docs/scene-format.md, `transform`).
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
    std::vector<std::array<double, 3>> index_pts;  // the same points in index space, for the host
    index_pts.reserve(pts.size());
    uint64_t h = 0x9e3779b97f4a7c15ull;
    auto u01 = [&] {
      h ^= h << 13, h ^= h >> 7, h ^= h << 17;
      return double(h >> 11) * (1.0 / 9007199254740992.0);
    };
    for (auto& p : pts) {
      std::array<double, 3> ip, wp{};
      for (int a = 0; a < 3; ++a) ip[a] = g.index_min[a] - 1 + u01() * (g.index_max[a] - g.index_min[a] + 2);
      index_pts.push_back(ip);
      for (int a = 0; a < 3; ++a)
        wp[a] = g.index_to_world[a][0] * ip[0] + g.index_to_world[a][1] * ip[1] + g.index_to_world[a][2] * ip[2] +
                g.index_to_world[a][3];
      wp = apply_transform(m.transform, wp);
      p = {float(wp[0]), float(wp[1]), float(wp[2])};
    }
    double sum = 0;
    Probe probe(r);
    const double t_density = best_time([&] {
      auto d = probe.density(medium, pts);
      sum = 0;
      for (float x : d) sum += x;
    });
    j["density"] = {{"points", n_points}, {"seconds", t_density}, {"lookups_per_second", double(n_points) / t_density},
                    {"mean_density", sum / double(n_points)}};
    // The same points with stochastic one-voxel lookups (--lookup stochastic, docs/stochastic-lookup.md): one
    // accessor walk and one read instead of eight, and one random draw; the mean density agrees
    // with the trilinear one within its noise.
    {
      RenderOptions so = opt;
      so.lookup = ST_LOOKUP_STOCHASTIC;
      Renderer rs(scene, so);
      Probe ps(rs);
      double ssum = 0;
      const double t_sto = best_time([&] {
        auto d = ps.density(medium, pts);
        ssum = 0;
        for (float x : d) ssum += x;
      });
      j["density"]["stochastic"] = {{"seconds", t_sto}, {"lookups_per_second", double(n_points) / t_sto},
                                    {"mean_density", ssum / double(n_points)}};
    }
    // The same trilinear lookups on the host with NanoVDB's ReadAccessor (one per thread), on 1
    // and 2 threads: the figure the kernels' PNanoVDB lookups are compared with (bench/RESULTS.md, 'PNanoVDB in the kernels against NanoVDB's host ReadAccessor').
    // The device figure includes the points' upload and the read-back; the host one does not.
    const nanovdb::FloatGrid* grid = g.handle.grid<float>();
    if (!grid) throw Error(scene_path + ": the medium's NanoVDB grid is not a float grid");
    auto host_lookups = [&](size_t begin, size_t end) {
      auto acc = grid->getAccessor();
      double s_local = 0;
      for (size_t i = begin; i < end; ++i) {
        const auto& ip = index_pts[i];
        const int x = int(std::floor(ip[0])), y = int(std::floor(ip[1])), z = int(std::floor(ip[2]));
        const double fx = ip[0] - x, fy = ip[1] - y, fz = ip[2] - z;
        double v[8];
        for (int c = 0; c < 8; ++c) v[c] = acc.getValue(nanovdb::Coord(x + (c & 1), y + ((c >> 1) & 1), z + ((c >> 2) & 1)));
        auto lerp = [](double a, double b, double t) { return a + (b - a) * t; };
        s_local += lerp(lerp(lerp(v[0], v[1], fx), lerp(v[2], v[3], fx), fy), lerp(lerp(v[4], v[5], fx), lerp(v[6], v[7], fx), fy), fz);
      }
      return s_local;
    };
    for (int threads : {1, 2}) {
      double host_sum = 0;
      const double t_host = best_time([&] {
        std::vector<std::future<double>> parts;
        const size_t n = index_pts.size();
        for (int k = 0; k < threads; ++k)
          parts.push_back(std::async(std::launch::async, host_lookups, n * size_t(k) / size_t(threads),
                                     n * size_t(k + 1) / size_t(threads)));
        host_sum = 0;
        for (auto& f : parts) host_sum += f.get();
      });
      j["density"]["host_read_accessor"][std::to_string(threads) + "_threads"] = {
          {"seconds", t_host}, {"lookups_per_second", double(n_points) / t_host}, {"mean_density", host_sum / double(n_points)}};
    }

    // The camera's central ray.
    const auto& c = scene.camera;
    const std::array<float, 3> o{float(c.position[0]), float(c.position[1]), float(c.position[2])};
    const std::array<float, 3> dir =
        unit({c.look_at[0] - c.position[0], c.look_at[1] - c.position[1], c.look_at[2] - c.position[2]});
    auto track = [&](Renderer& rr, int channel) {
      double lookups = 0, steps = 0, escaped = 0;
      Probe rr_probe(rr);
      const double t = best_time([&] {
        auto out = rr_probe.track(o, dir, channel, int(n_paths));
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
    const std::vector<std::string> trackers = {"delta-per-channel", "spectral", "decomposition", "spectral-decomposition", "spectral-mis"};
    for (const auto& name : trackers) {
      RenderOptions o2 = opt;
      o2.tracker = tracker_from_name(name);
      Renderer rr(scene, o2);
      const bool per_channel = name == "delta-per-channel" || name == "decomposition";
      j["track"][name] = track(rr, per_channel ? 0 : -1);
    }

    // (5) Shadow-ray transmittance, ratio tracking against ray marching (docs/transmittance.md): rays from
    // up to 32 of the points of (2) that lie in the medium, towards the first directional light
    // (else up, tilted), each estimated --paths / 4 times (64 to 1024) by both estimators with
    // the scene's tracker. The
    // figure of merit is variance x lookups per estimate (mean over rays and channels of the
    // per-ray variance, times the mean lookups), and the same with the probe's wall time.
    {
      std::array<float, 3> to_light = unit({0.3, 1.0, 0.2});
      for (const auto& l : scene.lights)
        if (l.type == ST_LIGHT_DIRECTIONAL) {
          to_light = unit({l.to_light[0], l.to_light[1], l.to_light[2]});
          break;
        }
      std::vector<float> dens = probe.density(medium, pts);
      std::vector<std::array<float, 3>> origins;
      for (size_t i = 0; i < pts.size() && origins.size() < 32; i += 97)
        if (dens[i] > 0.0f) origins.push_back(pts[i]);
      for (size_t i = 0; i < pts.size() && origins.empty(); ++i)  // a sparse volume: the first point inside
        if (dens[i] > 0.0f) origins.push_back(pts[i]);
      if (origins.empty()) throw Error(scene_path + ": no point of the density sample lies in the medium (shadow rays)");
      const int n_est = int(std::clamp<long>(n_paths / 4, 64, 1024));
      nlohmann::json& jt = j["shadow_transmittance"];
      jt["rays"] = origins.size();
      jt["estimates_per_ray"] = n_est;
      for (int mode : {ST_TRANSMITTANCE_RATIO, ST_TRANSMITTANCE_RAY_MARCHING}) {
        RenderOptions o2 = opt;
        o2.transmittance = mode;
        Renderer rr(scene, o2);
        Probe rp(rr);
        double var = 0, lookups = 0, mean = 0;
        const double t = best_time([&] {
          var = lookups = mean = 0;
          for (const auto& org : origins) {
            std::vector<std::array<float, 4>> stats;
            auto T = rp.transmittance(org, to_light, n_est, &stats);
            for (int ch = 0; ch < 3; ++ch) {
              double m1 = 0, m2 = 0;
              for (auto& x : T) m1 += x[ch], m2 += double(x[ch]) * x[ch];
              m1 /= n_est;
              var += (m2 / n_est - m1 * m1) * n_est / (n_est - 1.0);
              mean += m1;
            }
            for (auto& x : stats) lookups += x[0];
          }
        });
        const double rays = double(std::max<size_t>(1, origins.size()));
        var /= 3 * rays, mean /= 3 * rays, lookups /= rays * n_est;
        jt[transmittance_name(mode)] = {{"mean_T", mean},
                                        {"variance", var},
                                        {"lookups_per_estimate", lookups},
                                        {"seconds", t},
                                        {"variance_x_lookups", var * lookups},
                                        {"variance_x_seconds", var * t}};
      }
      jt["ratio_over_ray_marching_variance_x_lookups"] =
          jt["ratio"]["variance_x_lookups"].get<double>() / jt["ray-marching"]["variance_x_lookups"].get<double>();
      jt["ratio_over_ray_marching_variance_x_seconds"] =
          jt["ratio"]["variance_x_seconds"].get<double>() / jt["ray-marching"]["variance_x_seconds"].get<double>();
    }

    std::cout << fmt::format("device: {}\n", j["device"].get<std::string>());
    std::cout << fmt::format("kernel build: program {:.2f} s ({}), first launches +{:.2f} s, total {:.2f} s\n",
                             first.seconds_build, first.kernels_from_cache ? "from cache" : "compiled",
                             std::max(0.0, t_first - t_second), j["seconds_kernel_build_total"].get<double>());
    std::cout << fmt::format("density lookups: {:.3g}/s ({} points)\n", double(n_points) / t_density, n_points);
    for (const char* k : {"1_threads", "2_threads"}) {
      const double host = j["density"]["host_read_accessor"][k]["lookups_per_second"].get<double>();
      std::cout << fmt::format("  host NanoVDB ReadAccessor, {} thread(s): {:.3g}/s; kernel / host = {:.2f}\n", k[0], host,
                               (double(n_points) / t_density) / host);
    }
    std::cout << fmt::format("DDA cell steps (empty walk): {:.3g}/s ({:.1f} steps/path)\n",
                             j["dda"]["dda_steps_per_second"].get<double>(), j["dda"]["dda_steps_per_path"].get<double>());
    for (const auto& name : trackers) {
      const auto& t = j["track"][name];
      std::cout << fmt::format("{:<24} free paths {:.3g}/s, {:.2f} lookups/path, {:.2f} DDA steps/path, lookups {:.3g}/s\n",
                               name, t["paths_per_second"].get<double>(), t["lookups_per_path"].get<double>(),
                               t["dda_steps_per_path"].get<double>(), t["lookups_per_second"].get<double>());
    }
    {
      const auto& jt = j["shadow_transmittance"];
      for (const char* k : {"ratio", "ray-marching"})
        std::cout << fmt::format("shadow rays, {:<13} mean T {:.4f}, variance {:.3g}, {:.2f} lookups/estimate, {:.3f} s\n", k,
                                 jt[k]["mean_T"].get<double>(), jt[k]["variance"].get<double>(),
                                 jt[k]["lookups_per_estimate"].get<double>(), jt[k]["seconds"].get<double>());
      std::cout << fmt::format("shadow rays ({} rays x {}): ratio / ray-marching variance x lookups {:.2f}x, variance x "
                               "seconds {:.2f}x\n",
                               jt["rays"].get<size_t>(), jt["estimates_per_ray"].get<int>(),
                               jt["ratio_over_ray_marching_variance_x_lookups"].get<double>(),
                               jt["ratio_over_ray_marching_variance_x_seconds"].get<double>());
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
