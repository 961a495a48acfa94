// main.cpp: the spectrack command line (CLI11), shaped like pbrt's and Mitsuba's:
//   spectrack render SCENE [-o FILE] [--spp N | --spp-range A:B] [--pixel-bounds x0,x1,y0,y1]
//                    [--seed S] [--tracker T] [--scheme S] [--device D|all|D1,D2] [--mpi]
//                    [--stats-json FILE] [--preview FILE.png] [--quiet]
//   spectrack merge OUT.exr IN.exr... [--preview FILE.png]
//   (tuning: [--majorant-cell N] [--majorant-block N] [--generic-kernels] [--batches-in-flight N])
//   spectrack devices
// A render is a FilmPiece (render/film.h): the window and sample range it holds, with exact
// per-pixel sums; shards, tiles, devices and MPI ranks all combine through merge_pieces.
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
#include <filesystem>
#include <fstream>
#include <functional>
#include <future>
#include <tuple>
#include <iostream>
#include <unistd.h>

#include "cl/opencl.h"
#include "image/image.h"
#include "render/film.h"
#include "render/multi_device.h"
#include "render/renderer.h"
#include "render/stats_json.h"
#include "scene/scene.h"
#ifdef SPECTRACK_HAVE_MPI
#include "cli/mpi_render.h"
#endif

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
  std::string scene, output, stats_json, preview, device, tracker, scheme, spp_range, pixel_bounds;
  int spp = -1;
  int64_t seed = -1;
  int path_slots = 0;
  int budget = 256;
  int chunk_spp = 0;
  int majorant_cell = RenderOptions().majorant_cell;
  int majorant_block = RenderOptions().majorant_block;
  int batches_in_flight = 0;
  bool generic_kernels = false;
  bool quiet = false;
  bool mpi = false;
};

struct MergeArgs {
  std::string output, preview;
  std::vector<std::string> inputs;
  bool quiet = false;
};

// "A:B" with 0 <= A < B <= 2^32 and B - A <= 2^24 (a CLI11 check: a malformed range exits 2).
bool parse_spp_range(const std::string& text, int64_t* a, int64_t* b) {
  long long x = 0, y = 0;
  char extra = 0;
  if (std::sscanf(text.c_str(), "%lld:%lld%c", &x, &y, &extra) != 2) return false;
  if (text.find_first_not_of("0123456789:") != std::string::npos) return false;
  if (x < 0 || y <= x || y > (1LL << 32) || y - x > (1LL << 24)) return false;
  *a = x, *b = y;
  return true;
}

// "x0,x1,y0,y1" of non-negative integers with x0 < x1, y0 < y1 (the film size is checked later).
bool parse_pixel_bounds(const std::string& text, std::array<int, 4>* out) {
  int v[4];
  char extra = 0;
  if (text.find_first_not_of("0123456789,") != std::string::npos) return false;
  if (std::sscanf(text.c_str(), "%d,%d,%d,%d%c", &v[0], &v[1], &v[2], &v[3], &extra) != 4) return false;
  if (!(v[0] < v[1] && v[2] < v[3])) return false;
  *out = {v[0], v[1], v[2], v[3]};
  return true;
}

std::string join(const std::vector<std::string>& v, const char* sep) {
  std::string s;
  for (auto& x : v) s += (s.empty() ? "" : sep) + x;
  return s;
}

void write_stats_json(const std::string& path, const MultiDeviceResult& r, double seconds_total,
                      double seconds_to_renderer, int mpi_ranks) {
  nlohmann::json j = stats_to_json(r.stats);
  const FilmPiece& p = r.piece;
  j["spp"] = p.samples();
  j["spp_requested"] = r.spp_requested;
  j["spp_ranges"] = format_ranges(p.ranges);
  j["interrupted"] = p.interrupted;
  j["seed"] = r.seed;
  j["tracker"] = tracker_name(r.tracker);
  j["scheme"] = scheme_name(r.scheme);
  j["device"] = join(r.devices, ", ");
  j["devices"] = r.devices;
  j["samples_per_device"] = r.samples_per_device;
  j["mpi_ranks"] = mpi_ranks;
  j["width"] = p.width;
  j["height"] = p.height;
  j["full_width"] = p.id.full_width;
  j["full_height"] = p.id.full_height;
  j["pixel_bounds"] = {p.x0, p.x0 + p.width, p.y0, p.y0 + p.height};
  j["scene_hash"] = p.id.scene_hash;
  j["seconds_render"] = r.seconds_render;
  j["seconds_setup"] = r.seconds_setup;
  j["seconds_kernel_build"] = r.seconds_build;
  j["kernels_from_cache"] = r.kernels_from_cache;
  j["seconds_first_pass"] = r.seconds_first_pass;
  j["seconds_first_pass_from_start"] = seconds_to_renderer + r.seconds_first_pass;  // scene loading included
  j["features"] = r.features;
  j["generic_kernels"] = r.features == uint32_t(ST_FEATURES_ALL);
  j["seconds_total"] = seconds_total;
  j["paths_per_second"] = r.seconds_render > 0 ? double(r.stats.paths) / r.seconds_render : 0.0;
  std::ofstream f(path);
  if (!f) throw Error(fmt::format("{}: cannot write stats file", path));
  f << j.dump(2) << "\n";
}

struct MpiArg {
  bool on = false;
  int rank = 0, size = 1;
#ifdef SPECTRACK_HAVE_MPI
  MpiWorld world;
#endif
};

int cmd_render(const RenderArgs& a, MpiArg& mpi) {
  auto t0 = std::chrono::steady_clock::now();
  const bool root = mpi.rank == 0;
  const bool quiet = a.quiet || !root;
  SceneDesc scene = load_scene(a.scene);
  RenderOptions opt;
  opt.seed = a.seed;
  opt.quiet = quiet;
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
  int64_t begin = 0;
  int spp = a.spp > 0 ? a.spp : scene.film.spp;
  if (!a.spp_range.empty()) {
    int64_t b = 0;
    parse_spp_range(a.spp_range, &begin, &b);  // checked by CLI11 already
    spp = int(b - begin);
  }
  opt.spp = spp;
  opt.sample_begin = begin;
  if (!a.pixel_bounds.empty()) {
    parse_pixel_bounds(a.pixel_bounds, &opt.pixel_bounds);
    auto [x0, x1, y0, y1] = opt.pixel_bounds;
    if (x1 > scene.film.width || y1 > scene.film.height)
      throw Error(fmt::format("--pixel-bounds {}: the window x {}..{}, y {}..{} leaves the {}x{} film of {} "
                              "(/film/width, /film/height)",
                              a.pixel_bounds, x0, x1 - 1, y0, y1 - 1, scene.film.width, scene.film.height, scene.path));
  }
  std::string output = a.output.empty() ? scene.film.output : a.output;
  if (root) {
    check_output_path(output);
    if (!a.preview.empty()) check_output_path(a.preview);
    if (!a.stats_json.empty()) check_writable_file(a.stats_json);
  }
  std::vector<std::string> devices = parse_device_list(a.device);
#ifdef SPECTRACK_HAVE_MPI
  if (mpi.on && devices.size() == 1 && devices[0].empty()) devices[0] = mpi_default_device(mpi.world);
#endif
  RenderIdentity id = render_identity(scene, opt);
  // The scene hash reads every VDB and map once more: on the writing rank only, beside the render.
  std::future<std::string> hash;
  if (root) hash = std::async(std::launch::async, [&scene] { return scene_hash(scene); });

  bool tty = ::isatty(2);
  int last_pct = -10;
  std::function<void(double)> progress = [&](double f) {
    if (quiet) return;
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
  opt.progress = progress;
  opt.stop = &g_stop;
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);

  // this process's share of the samples (all of them without MPI)
  int64_t my_begin = begin, my_end = begin + spp;
#ifdef SPECTRACK_HAVE_MPI
  if (mpi.on) std::tie(my_begin, my_end) = mpi_sample_share(mpi.world, begin, spp);
#endif
  if (!quiet)
    std::cerr << fmt::format("spectrack: {} on {} ({}x{}{}, samples {}:{}, tracker {}, scheme {}{})\n", scene.path,
                             devices.size() == 1 && devices[0].empty() ? select_device("").name : join(devices, ","),
                             scene.film.width, scene.film.height,
                             a.pixel_bounds.empty() ? "" : ", pixels " + a.pixel_bounds, begin, begin + spp,
                             id.tracker, id.scheme, mpi.on ? fmt::format(", {} MPI ranks", mpi.size) : "");
  const double seconds_to_renderer = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  MultiDeviceResult r;
  if (my_end > my_begin) {
    r = render_multi_device(scene, opt, devices, id, my_begin, int(my_end - my_begin), a.chunk_spp);
  } else {  // an MPI rank with no samples (more ranks than samples) contributes zeros
    auto [x0, x1, y0, y1] = opt.pixel_bounds;
    if (x1 < 0) x0 = 0, x1 = scene.film.width, y0 = 0, y1 = scene.film.height;
    r.piece.id = id;
    r.piece.x0 = x0, r.piece.y0 = y0, r.piece.width = x1 - x0, r.piece.height = y1 - y0;
    r.piece.sum.assign(size_t(r.piece.width) * r.piece.height * 3, 0.0);
  }
  r.spp_requested = spp;
  r.tracker = tracker_from_name(id.tracker);
  r.scheme = scheme_from_name(id.scheme);
  r.seed = uint32_t(id.seed);
  r.piece.interrupted = r.piece.interrupted || r.piece.samples() < my_end - my_begin;
#ifdef SPECTRACK_HAVE_MPI
  if (mpi.on) mpi_reduce_to_root(mpi.world, r);
#endif
  if (root) r.piece.interrupted = r.piece.interrupted || r.piece.samples() < spp;
  if (tty && !quiet) std::fprintf(stderr, "\n");
  if (!root) return r.piece.interrupted ? 130 : 0;
  r.piece.id.scene_hash = hash.get();
  double total = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  Metadata meta;
  meta["spp_requested"] = spp;
  meta["device"] = join(r.devices, ", ");
  meta["render_seconds"] = float(r.seconds_render);
  meta["scene"] = scene.path;
  if (mpi.on) meta["mpi_ranks"] = mpi.size;
  write_piece(output, r.piece, meta);
  if (!a.preview.empty()) write_piece(a.preview, r.piece, meta);
  if (!a.stats_json.empty()) write_stats_json(a.stats_json, r, total, seconds_to_renderer, mpi.size);
  if (r.stats.nonfinite_samples > 0)
    std::cerr << fmt::format("warning: {} non-finite samples were dropped (counted in nonfinite_samples)\n",
                             r.stats.nonfinite_samples);
  if (!a.quiet)
    std::cerr << fmt::format("wrote {} ({} spp in {:.2f} s render, {:.2f} s total{})\n", output, r.piece.samples(),
                             r.seconds_render, total, r.piece.interrupted ? ", INTERRUPTED" : "");
  return r.piece.interrupted ? 130 : 0;
}

int cmd_merge(const MergeArgs& a) {
  std::string ext = std::filesystem::path(a.output).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  if (ext != ".exr") throw Error(fmt::format("{}: the merged image must be an EXR (use --preview for a PNG)", a.output));
  check_output_path(a.output);
  if (!a.preview.empty()) check_output_path(a.preview);
  std::error_code ec;
  std::vector<FilmPiece> pieces;
  double seconds = 0;
  std::vector<std::string> devices;
  std::string scene;
  for (auto& in : a.inputs) {
    if (std::filesystem::exists(a.output, ec) && std::filesystem::equivalent(in, a.output, ec))
      throw Error(fmt::format("{}: is both an input and the output of the merge", in));
    Metadata head;  // the other metadata, for the record
    pieces.push_back(read_piece(in, &head));
    if (auto f = head.find("render_seconds"); f != head.end() && std::holds_alternative<float>(f->second))
      seconds += std::get<float>(f->second);
    if (auto d = head.find("device"); d != head.end() && std::holds_alternative<std::string>(d->second))
      if (std::find(devices.begin(), devices.end(), std::get<std::string>(d->second)) == devices.end())
        devices.push_back(std::get<std::string>(d->second));
    if (auto s = head.find("scene"); s != head.end() && std::holds_alternative<std::string>(s->second))
      scene = std::get<std::string>(s->second);
    if (pieces.back().interrupted && !a.quiet)
      std::cerr << fmt::format("warning: {} is an interrupted render: it holds samples {} only\n", in,
                               format_ranges(pieces.back().ranges));
  }
  FilmPiece m = merge_pieces(pieces);
  Metadata meta;
  meta["render_seconds"] = float(seconds);
  meta["device"] = join(devices, ", ");
  meta["scene"] = scene;
  meta["merged_inputs"] = int(pieces.size());
  write_piece(a.output, m, meta);
  if (!a.preview.empty()) write_piece(a.preview, m, meta);
  if (!a.quiet)
    std::cerr << fmt::format("merged {} inputs: samples {} of pixels {},{},{},{} (x0,x1,y0,y1) of the {}x{} film -> {}\n",
                             pieces.size(), format_ranges(m.ranges), m.x0, m.x0 + m.width, m.y0, m.y0 + m.height,
                             m.id.full_width, m.id.full_height, a.output);
  return 0;
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
  auto* o_spp = render->add_option("--spp", ra.spp, "samples per pixel (overrides film.spp)")->check(CLI::Range(1, 1 << 24));
  render->add_option("--spp-range", ra.spp_range,
                     "render samples A..B-1 of every pixel of the full sequence (a shard; merge with `spectrack merge`)")
      ->check(CLI::Validator(
          [](std::string& v) {
            int64_t a = 0, b = 0;
            return parse_spp_range(v, &a, &b) ? std::string()
                                              : "expected A:B with 0 <= A < B <= 2^32 and B - A <= 2^24, got '" + v + "'";
          },
          "A:B"))
      ->excludes(o_spp);
  render->add_option("--pixel-bounds", ra.pixel_bounds,
                     "render only pixels x0..x1-1, y0..y1-1 of the film (a tile; merge with `spectrack merge`)")
      ->check(CLI::Validator(
          [](std::string& v) {
            std::array<int, 4> b;
            return parse_pixel_bounds(v, &b) ? std::string()
                                             : "expected x0,x1,y0,y1 with 0 <= x0 < x1 and 0 <= y0 < y1, got '" + v + "'";
          },
          "x0,x1,y0,y1"));
  render->add_option("--seed", ra.seed, "random seed (overrides render.seed)")->check(CLI::Range(int64_t(0), int64_t(4294967295LL)));
  render->add_option("--tracker", ra.tracker, "delta-per-channel, delta, spectral, decomposition, spectral-decomposition");
  render->add_option("--scheme", ra.scheme, "spectral scheme: max, average, history-max, history-average");
  render->add_option("--device", ra.device,
                     "OpenCL device: P:D or a name substring, 'all', or a comma-separated list to share the samples "
                     "(env SPECTRACK_DEVICE)");
  render->add_option("--chunk-spp", ra.chunk_spp, "samples per pixel a device takes at a time with several devices")
      ->check(CLI::Range(1, 1 << 24));
  render->add_flag("--mpi", ra.mpi, "under mpirun: each rank renders a disjoint sample range, rank 0 writes the image");
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
  MergeArgs ma;
  auto* merge = app.add_subcommand("merge", "combine sample-range shards and tiles (EXR) into one EXR");
  merge->add_option("output", ma.output, "the merged EXR")->required();
  merge->add_option("inputs", ma.inputs, "EXR outputs of `spectrack render` (shards and/or tiles)")->required()->expected(1, -1);
  merge->add_option("--preview", ma.preview, "also write a PNG preview");
  merge->add_flag("-q,--quiet", ma.quiet, "no summary line");
  app.add_subcommand("devices", "list OpenCL platforms and devices");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  MpiArg mpi;
  try {
    if (app.got_subcommand("devices")) return cmd_devices();
    if (app.got_subcommand("merge")) return cmd_merge(ma);
    if (ra.mpi) {
#ifdef SPECTRACK_HAVE_MPI
      mpi.world = mpi_start(&argc, &argv);
      mpi.on = true;
      mpi.rank = mpi.world.rank;
      mpi.size = mpi.world.size;
#else
      throw Error("--mpi: this spectrack was built without MPI (install libopenmpi-dev and rebuild; CMake finds it)");
#endif
    }
    int code = cmd_render(ra, mpi);
#ifdef SPECTRACK_HAVE_MPI
    if (mpi.on) mpi_finish();
#endif
    return code;
  } catch (const std::exception& e) {
    std::cerr << (mpi.on && mpi.size > 1 ? fmt::format("error (MPI rank {}): ", mpi.rank) : std::string("error: "))
              << e.what() << "\n";
#ifdef SPECTRACK_HAVE_MPI
    if (mpi.on && mpi.size > 1) mpi_abort(1);  // the other ranks would wait in the reduction for ever
    if (mpi.on) mpi_finish();
#endif
    return 1;
  }
}
