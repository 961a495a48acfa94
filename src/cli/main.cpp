// main.cpp: the spectrack command line (CLI11), shaped like pbrt's and Mitsuba's:
//   spectrack render SCENE [-o FILE] [--spp N] [--seed S] [--tracker T] [--scheme S] [--device D]
//                    [--stats-json FILE] [--preview FILE.png] [--quiet]
//                    [--majorant-cell N] [--majorant-block N] [--generic-kernels] [--batches-in-flight N]
//   spectrack devices
// Exit codes: 0 success; 1 a user-facing error (message on stderr names file, field and reason);
// 2 bad command line; 130 interrupted (the image of the finished samples is still written and
// marked `interrupted` in its metadata).
#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <unistd.h>

#include "cl/opencl.h"
#include "image/image.h"
#include "render/renderer.h"
#include "scene/scene.h"

using namespace spectrack;

namespace {

std::atomic<bool> g_stop{false};

extern "C" void on_signal(int sig) {
  if (g_stop.load()) {  // a second signal ends the process at once
    std::signal(sig, SIG_DFL);
    std::raise(sig);
    return;
  }
  g_stop.store(true);
}

int cmd_devices() {
  auto devs = enumerate_devices(true);
  if (devs.empty()) {
    std::cerr << "no OpenCL device found (install pocl-opencl-icd or a GPU driver)\n";
    return 1;
  }
  std::cout << fmt::format("{:<5} {:<44} {:<5} {:>4} {:>11} {:>11}  {}\n", "P:D", "device", "type", "CUs",
                           "memory MiB", "max alloc", "platform");
  for (auto& d : devs)
    std::cout << fmt::format("{:<5} {:<44} {:<5} {:>4} {:>11} {:>11}  {} ({})\n",
                             fmt::format("{}:{}", d.platform_index, d.device_index), d.name, d.type_name(),
                             d.compute_units, d.global_mem >> 20, d.max_alloc >> 20, d.platform_name, d.driver_version);
  return 0;
}

struct RenderArgs {
  std::string scene, output, stats_json, preview, device, tracker, scheme;
  int spp = -1;
  int64_t seed = -1;
  int path_slots = 0;
  int budget = 256;
  int majorant_cell = RenderOptions().majorant_cell;
  int majorant_block = RenderOptions().majorant_block;
  int batches_in_flight = 0;
  bool generic_kernels = false;
  bool quiet = false;
};

void write_stats_json(const std::string& path, const RenderResult& r, double seconds_total, double seconds_to_renderer) {
  nlohmann::json j;
  j["spp"] = r.spp_done;
  j["spp_requested"] = r.spp_requested;
  j["interrupted"] = r.interrupted;
  j["seed"] = r.seed;
  j["tracker"] = tracker_name(r.tracker);
  j["scheme"] = scheme_name(r.scheme);
  j["device"] = r.device;
  j["width"] = r.width;
  j["height"] = r.height;
  j["seconds_render"] = r.seconds_render;
  j["seconds_setup"] = r.seconds_setup;
  j["seconds_kernel_build"] = r.seconds_build;
  j["kernels_from_cache"] = r.kernels_from_cache;
  j["seconds_first_pass"] = r.seconds_first_pass;
  j["seconds_first_pass_from_start"] = seconds_to_renderer + r.seconds_first_pass;  // scene loading included
  j["features"] = r.features;
  j["generic_kernels"] = r.features == uint32_t(ST_FEATURES_ALL);
  j["seconds_total"] = seconds_total;
  const RenderStats& s = r.stats;
  j["paths"] = s.paths;
  j["density_lookups"] = s.lookups_track + s.lookups_shadow;
  j["density_lookups_tracking"] = s.lookups_track;
  j["density_lookups_shadow"] = s.lookups_shadow;
  j["emission_lookups"] = s.lookups_emission;
  j["real_collisions"] = s.real_collisions;
  j["null_collisions"] = s.null_collisions;
  j["control_collisions"] = s.control_collisions;
  j["residual_collisions"] = s.residual_collisions;
  j["scatter_events"] = s.scatter_events;
  j["dda_steps"] = s.dda_steps;
  j["dda_steps_nonempty"] = s.dda_nonempty;
  j["occupancy_mean"] = s.occupancy_mean;
  j["occupancy_min"] = s.occupancy_min;
  j["iterations_below_half_occupancy"] = s.iterations_below_half;
  j["requeues"] = s.requeues;
  j["iterations"] = s.iterations;
  j["nonfinite_samples"] = s.nonfinite_samples;
  j["max_throughput"] = s.max_throughput;
  j["paths_per_second"] = r.seconds_render > 0 ? double(s.paths) / r.seconds_render : 0.0;
  for (auto& [name, t] : s.kernels) j["kernels"][name] = {{"seconds", t.seconds}, {"launches", t.launches}};
  std::ofstream f(path);
  if (!f) throw Error(fmt::format("{}: cannot write stats file", path));
  f << j.dump(2) << "\n";
}

int cmd_render(const RenderArgs& a) {
  auto t0 = std::chrono::steady_clock::now();
  SceneDesc scene = load_scene(a.scene);
  RenderOptions opt;
  opt.spp = a.spp;
  opt.seed = a.seed;
  opt.device = a.device;
  opt.quiet = a.quiet;
  opt.path_slots = a.path_slots;
  opt.iteration_budget = a.budget;
  opt.majorant_cell = a.majorant_cell;
  opt.majorant_block = a.majorant_block;
  opt.generic_kernels = a.generic_kernels;
  opt.batches_in_flight = a.batches_in_flight;
  if (!a.tracker.empty()) {
    opt.tracker = tracker_from_name(a.tracker);
    if (opt.tracker < 0) throw Error(fmt::format("--tracker {}: unknown tracker (one of: {})", a.tracker, tracker_names()));
  }
  if (!a.scheme.empty()) {
    opt.scheme = scheme_from_name(a.scheme);
    if (opt.scheme < 0) throw Error(fmt::format("--scheme {}: unknown scheme (one of: {})", a.scheme, scheme_names()));
  }
  std::string output = a.output.empty() ? scene.film.output : a.output;
  check_output_path(output);
  if (!a.preview.empty()) check_output_path(a.preview);
  if (!a.stats_json.empty()) check_writable_file(a.stats_json);

  bool tty = ::isatty(2);
  int last_pct = -10;
  opt.progress = [&](double f) {
    if (a.quiet) return;
    int pct = int(f * 100.0);
    if (tty) {
      int bar = int(f * 40.0);
      std::fprintf(stderr, "\r[%-40s] %3d%%", std::string(size_t(bar), '#').c_str(), pct);
      std::fflush(stderr);
    } else if (pct / 10 != last_pct / 10 || pct == 100) {
      if (pct != last_pct) std::fprintf(stderr, "progress: %d%%\n", pct);
    }
    last_pct = pct;
  };
  opt.stop = &g_stop;
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);

  const double seconds_to_renderer = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  Renderer renderer(scene, opt);
  if (!a.quiet)
    std::cerr << fmt::format("spectrack: {} on {} ({}x{}, {} spp, tracker {}, scheme {})\n", scene.path,
                             renderer.device_name(), scene.film.width, scene.film.height,
                             a.spp > 0 ? a.spp : scene.film.spp, tracker_name(opt.tracker >= 0 ? opt.tracker : scene.render.tracker),
                             scheme_name(opt.scheme >= 0 ? opt.scheme : scene.render.scheme));
  RenderResult r = renderer.render();
  if (tty && !a.quiet) std::fprintf(stderr, "\n");
  double total = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  Metadata meta;
  meta["spp"] = r.spp_done;
  meta["spp_requested"] = r.spp_requested;
  meta["seed"] = int(r.seed);
  meta["tracker"] = std::string(tracker_name(r.tracker));
  meta["scheme"] = std::string(scheme_name(r.scheme));
  meta["device"] = r.device;
  meta["render_seconds"] = float(r.seconds_render);
  meta["version"] = std::string(SPECTRACK_VERSION);
  meta["scene"] = scene.path;
  meta["interrupted"] = r.interrupted ? 1 : 0;
  write_image(output, r.width, r.height, r.rgb, meta);
  if (!a.preview.empty()) write_image(a.preview, r.width, r.height, r.rgb, meta);
  if (!a.stats_json.empty()) write_stats_json(a.stats_json, r, total, seconds_to_renderer);
  if (r.stats.nonfinite_samples > 0)
    std::cerr << fmt::format("warning: {} non-finite samples were dropped (counted in nonfinite_samples)\n",
                             r.stats.nonfinite_samples);
  if (!a.quiet)
    std::cerr << fmt::format("wrote {} ({} spp in {:.2f} s render, {:.2f} s total{})\n", output, r.spp_done,
                             r.seconds_render, total, r.interrupted ? ", INTERRUPTED" : "");
  return r.interrupted ? 130 : 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"spectrack: spectral and decomposition tracking for heterogeneous volumes on OpenCL"};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string("spectrack ") + SPECTRACK_VERSION);
  RenderArgs ra;
  auto* render = app.add_subcommand("render", "render a scene file to EXR or PNG");
  render->add_option("scene", ra.scene, "scene file (spectrack-scene/1 JSON)")->required();
  render->add_option("-o,--output", ra.output, "output image (.exr or .png); default: the scene's film.output");
  render->add_option("--spp", ra.spp, "samples per pixel (overrides film.spp)")->check(CLI::Range(1, 1 << 24));
  render->add_option("--seed", ra.seed, "random seed (overrides render.seed)")->check(CLI::Range(int64_t(0), int64_t(4294967295LL)));
  render->add_option("--tracker", ra.tracker, "delta-per-channel, delta, spectral, decomposition, spectral-decomposition");
  render->add_option("--scheme", ra.scheme, "spectral scheme: max, average, history-max, history-average");
  render->add_option("--device", ra.device, "OpenCL device: P:D or a name substring (env SPECTRACK_DEVICE)");
  render->add_option("--stats-json", ra.stats_json, "write render statistics as JSON");
  render->add_option("--preview", ra.preview, "also write a PNG preview");
  render->add_option("--path-slots", ra.path_slots, "paths in flight (default: 65536 on CPUs, 1M on GPUs)")->check(CLI::Range(1, 1 << 24));
  render->add_option("--budget", ra.budget, "tracking iterations per path and kernel launch")->check(CLI::Range(1, 1 << 20));
  render->add_option("--majorant-cell", ra.majorant_cell, "voxels per majorant-grid cell edge")
      ->check(CLI::Range(1, 1024))
      ->capture_default_str();
  render->add_option("--majorant-block", ra.majorant_block,
                     "cells per coarse-block edge of a two-level majorant grid (0 or 1: one level)")
      ->check(CLI::Range(0, 1024))
      ->capture_default_str();
  render->add_option("--batches-in-flight", ra.batches_in_flight,
                     "batches of samples in flight, 1-" + std::to_string(ST_MAX_BATCHES_IN_FLIGHT) + " (default: the maximum)")
      ->check(CLI::Range(1, ST_MAX_BATCHES_IN_FLIGHT));
  render->add_flag("--generic-kernels", ra.generic_kernels, "use the generic kernels instead of ones specialised to the scene");
  render->add_flag("-q,--quiet", ra.quiet, "no progress output");
  app.add_subcommand("devices", "list OpenCL platforms and devices");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  try {
    if (app.got_subcommand("devices")) return cmd_devices();
    return cmd_render(ra);
  } catch (const Error& e) {
    std::cerr << "error: " << e.what() << "\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "error: " << e.what() << "\n";
    return 1;
  }
}
