// main.cpp: the spectrack command line (CLI11), shaped like pbrt's and Mitsuba's:
//   spectrack render SCENE [-o FILE] [--spp N | --spp-range A:B] [--pixel-bounds x0,x1,y0,y1]
//                    [--seed S] [--tracker T] [--scheme S] [--device D|all|D1,D2] [--mpi]
//                    [--stats-json FILE] [--preview FILE.png] [--quiet]
//   spectrack merge OUT.exr IN.exr... [--preview FILE.png]   (cli/merge.cpp)
//   (tuning: [--majorant-cell N] [--majorant-block N] [--generic-kernels] [--batches-in-flight N])
//   spectrack devices
//   spectrack info FILE... [--json]   (cli/info.cpp)
// The values of the options are checked by the validators of cli/options.h (exit 2).
// A render is a FilmPiece (render/film.h): the window and sample range it holds, with exact
// per-pixel sums; shards, tiles, devices and MPI ranks all combine through merge_pieces.
// Exit codes: 0 success; 1 a user-facing error (message on stderr names file, field and reason);
// 2 bad command line; 3 the time limit came before any sample finished (nothing written);
// 130 interrupted (the image of the finished samples is still written and marked `interrupted`
// in its metadata; cli/run_control.h).
#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstdint>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <future>
#include <memory>
#include <sstream>
#include <tuple>
#include <iostream>
#include <unistd.h>

#include "cli/checks.h"
#include "cli/merge.h"
#include "cli/options.h"
#include "cl/opencl.h"
#include "cli/info.h"
#include "cli/progress.h"
#include "cli/render_outputs.h"
#include "render/render_watch.h"
#include "cli/run_control.h"
#include "image/image.h"
#include "render/film.h"
#include "render/multi_device.h"
#include "render/renderer.h"
#include "scene/frames.h"
#include "scene/scene.h"
#ifdef SPECTRACK_HAVE_MPI
#include "cli/mpi_render.h"
#endif

using namespace spectrack;
namespace fs = std::filesystem;

namespace {

int cmd_devices() {
  auto devs = enumerate_devices(true);
  if (devs.empty()) {
    std::cerr << "no OpenCL device found (install pocl-opencl-icd or a GPU driver)\n";
    return 1;
  }
  // columns as wide as their longest entry, whatever the device names
  size_t wname = 6, wtype = 4;
  for (auto& d : devs) wname = std::max(wname, d.name.size()), wtype = std::max(wtype, std::string(d.type_name()).size());
  std::cout << fmt::format("{:<5} {:<{}} {:<{}} {:>4} {:>11} {:>11}  {}\n", "P:D", "device", wname, "type", wtype, "CUs",
                           "memory MiB", "max alloc", "platform");
  for (auto& d : devs)
    std::cout << fmt::format("{:<5} {:<{}} {:<{}} {:>4} {:>11} {:>11}  {} ({})\n",
                             fmt::format("{}:{}", d.platform_index, d.device_index), d.name, wname, d.type_name(), wtype,
                             d.compute_units, d.global_mem >> 20, d.max_alloc >> 20, d.platform_name, d.driver_version);
  return 0;
}

struct RenderArgs {
  std::string scene, output, stats_json, preview, device, tracker, scheme, absorption, light_sampling, transmittance,
      lookup, spp_range, pixel_bounds, frames, aov, compression, guiding;
  bool alpha = false, no_alpha = false, half = false, spectral = false;
  double march_spacing = 0, pilot_spacing = 0;  // 0: not given
  int spp = -1;
  int64_t seed = -1;
  int path_slots = 0;
  int budget = 256;
  int chunk_spp = 0;
  int majorant_cell = RenderOptions().majorant_cell;
  int majorant_block = RenderOptions().majorant_block;
  double majorant_step_cost = RenderOptions().majorant_step_cost;
  int batches_in_flight = 0;
  int shadow_ring = 0;
  uint32_t feature_floor = 0;  // RenderOptions::feature_floor (frame sequences)
  double time_limit = 0;
  double noise_target = 0;  // 0: not given
  double checkpoint = 0;    // seconds between checkpoints; 0: none
  bool resume = false;
  bool generic_kernels = false;
  bool quiet = false;
  bool mpi = false;
};

std::string join(const std::vector<std::string>& v, const char* sep) {
  std::string s;
  for (auto& x : v) s += (s.empty() ? "" : sep) + x;
  return s;
}

struct MpiArg {
  bool on = false;
  int rank = 0, size = 1;
#ifdef SPECTRACK_HAVE_MPI
  MpiWorld world;
#endif
};

// The command line's overrides of the scene (the flags CLI11 has already range-checked).
RenderOptions render_options(const RenderArgs& a, bool quiet) {
  RenderOptions opt;
  if (a.seed >= 0) opt.seed = a.seed;
  opt.quiet = quiet;
  opt.path_slots = a.path_slots;
  opt.iteration_budget = a.budget;
  opt.majorant_cell = a.majorant_cell;
  opt.majorant_block = a.majorant_block;
  opt.majorant_step_cost = a.majorant_step_cost;
  opt.generic_kernels = a.generic_kernels;
  opt.batches_in_flight = a.batches_in_flight;
  opt.shadow_ring = a.shadow_ring;
  opt.feature_floor = a.feature_floor;
  if (!a.tracker.empty()) {
    opt.tracker = tracker_from_name(a.tracker);
    if (*opt.tracker < 0) throw Error(fmt::format("--tracker {}: unknown tracker (one of: {})", a.tracker, tracker_names()));
  }
  if (!a.scheme.empty()) {
    opt.scheme = scheme_from_name(a.scheme);
    if (*opt.scheme < 0) throw Error(fmt::format("--scheme {}: unknown scheme (one of: {})", a.scheme, scheme_names()));
  }
  if (!a.light_sampling.empty()) {
    opt.light_sampling = light_sampling_from_name(a.light_sampling);
    if (*opt.light_sampling < 0)
      throw Error(fmt::format("--light-sampling {}: unknown light sampling (one of: {})", a.light_sampling,
                              light_sampling_names()));
  }
  if (!a.transmittance.empty()) {
    opt.transmittance = transmittance_from_name(a.transmittance);
    if (*opt.transmittance < 0)
      throw Error(fmt::format("--transmittance {}: unknown transmittance estimator (one of: {})", a.transmittance,
                              transmittance_names()));
  }
  if (!a.lookup.empty()) {
    opt.lookup = lookup_from_name(a.lookup);
    if (*opt.lookup < 0)
      throw Error(fmt::format("--lookup {}: unknown density lookup mode (one of: {})", a.lookup, lookup_names()));
  }
  if (!a.guiding.empty()) opt.guiding = guiding_from_name(a.guiding);  // checked by CLI11
  if (a.spectral) opt.color = ST_FILM_COLOR_SPECTRAL;
  if (a.march_spacing > 0) opt.march_spacing = a.march_spacing;
  if (a.pilot_spacing > 0) opt.pilot_spacing = a.pilot_spacing;
  if (!a.absorption.empty()) {
    opt.absorption = absorption_from_name(a.absorption);
    if (*opt.absorption < 0)
      throw Error(fmt::format("--absorption {}: unknown absorption mode (one of: {})", a.absorption, absorption_names()));
  }
  if (a.spp > 0) opt.spp = a.spp;
  if (a.noise_target > 0) opt.noise_target = a.noise_target;
  if (!a.spp_range.empty()) {
    int64_t b = 0;
    check_spp_range(a.spp_range, &opt.sample_begin, &b);  // checked by CLI11 already
    opt.spp = int(b - opt.sample_begin);
  }
  if (!a.pixel_bounds.empty()) {
    std::array<int, 4> bounds;
    check_pixel_bounds(a.pixel_bounds, &bounds);  // checked by CLI11 already
    opt.pixel_bounds = bounds;
  }
  return opt;
}

// How many samples this process renders (its share under MPI), for the progress line.
int64_t process_samples(const RenderSettings& set, MpiArg& mpi) {
  int64_t my_begin = set.sample_begin, my_end = set.sample_begin + set.spp;
#ifdef SPECTRACK_HAVE_MPI
  if (mpi.on) std::tie(my_begin, my_end) = mpi_sample_share(mpi.world, set.sample_begin, set.spp);
#endif
  return std::max<int64_t>(my_end - my_begin, 0);
}

// This process's share of the samples rendered on its devices (an MPI rank with no samples, when
// there are more ranks than samples, contributes an empty piece), reduced to rank 0 under MPI.
MultiDeviceResult render_share(const SceneDesc& scene, const RenderOptions& opt, const RenderSettings& set,
                               const std::vector<std::string>& devices, int chunk_spp, MpiArg& mpi) {
  int64_t my_begin = set.sample_begin, my_end = set.sample_begin + set.spp;
#ifdef SPECTRACK_HAVE_MPI
  if (mpi.on) std::tie(my_begin, my_end) = mpi_sample_share(mpi.world, set.sample_begin, set.spp);
#endif
  MultiDeviceResult r;
  if (my_end > my_begin) {
    r = render_multi_device(scene, opt, set, devices, my_begin, int(my_end - my_begin), chunk_spp);
  } else {
    r.piece = empty_piece(render_identity(set), set.window, "render");
    r.record_settings(set);
    r.light_sampling_used = set.light_sampling;  // no scene packed here: the request ("auto" unresolved)
  }
  r.spp_requested = set.spp;
  r.piece.interrupted = r.piece.interrupted || (r.piece.samples() < my_end - my_begin && !r.noise_target_reached);
#ifdef SPECTRACK_HAVE_MPI
  if (mpi.on) mpi_reduce_to_root(mpi.world, r);
#endif
  if (mpi.rank == 0) r.piece.interrupted = r.piece.interrupted || (r.piece.samples() < set.spp && !r.noise_target_reached);
  return r;
}

// The film layers of a render to `output` (docs/aov.md): film.aovs and --aov; alpha from --alpha /
// --no-alpha, else film.alpha, else on for an EXR output. Layers need an EXR (a PNG holds the beauty).
uint32_t film_layers(const RenderArgs& a, const SceneDesc& scene, const std::string& output) {
  uint32_t aovs = scene.film.aovs & ~uint32_t(ST_AOV_BIT(ALPHA));
  std::stringstream list(a.aov);
  std::string name;
  bool alpha_listed = false;
  while (std::getline(list, name, ',')) {
    const int k = aov_from_name(name);
    if (k < 0) throw Error(fmt::format("--aov {}: unknown layer '{}' (one of: {})", a.aov, name, aov_names()));
    if (k == ST_AOV_INDEX_ALPHA) alpha_listed = true;
    else aovs |= 1u << k;
  }
  std::string ext = std::filesystem::path(output).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  const bool exr = ext == ".exr";
  if (a.alpha && a.no_alpha) throw Error("--alpha and --no-alpha: choose one");
  if (alpha_listed && a.no_alpha) throw Error(fmt::format("--aov {} lists alpha, which --no-alpha turns off", a.aov));
  bool alpha = a.alpha || alpha_listed ? true : a.no_alpha ? false : scene.film.alpha.value_or(exr);
  if (!exr && (aovs || ((a.alpha || alpha_listed || scene.film.alpha.value_or(false)) && !a.no_alpha)))
    throw Error(fmt::format("{}: film layers ({}) need an EXR output; a PNG holds the beauty only (write an EXR and add "
                            "--preview for a PNG)",
                            output, a.aov.empty() ? std::string("film.aovs / film.alpha of ") + scene.path : "--aov " + a.aov));
  if (!exr) alpha = false;
  return aovs | (alpha ? uint32_t(ST_AOV_BIT(ALPHA)) : 0u);
}

ExrOptions exr_options(bool half, const std::string& compression, const FilmDesc& film) {
  ExrOptions o;
  o.half = half || film.half;
  o.compression = compression.empty() ? film.compression : compression;
  return o;
}

// What the watch of a render (cli/render_watch.h) needs, or nothing when no flag asks for it. It
// looks at one device's film in one process: a noise target, checkpoints and --resume refuse
// several devices and --mpi (exit 2), a noise target also shards and tiles (each would stop at
// its own noise); a preview with several devices or ranks is written at the end only.
std::unique_ptr<RenderWatch> make_watch(const RenderArgs& a, const MpiArg& mpi, const SceneDesc& scene,
                                        const RenderSettings& set, const std::vector<std::string>& devices,
                                        const std::string& output, const std::function<std::string()>& hash) {
  const bool several = devices.size() > 1 || mpi.on;
  if (set.noise_target > 0 && several)
    throw UsageError("--noise-target (render.noise_target) stops one device's render at its noise: it does not work "
                     "with several devices or --mpi");
  if (set.noise_target > 0 && (!a.spp_range.empty() || !a.pixel_bounds.empty()))
    throw UsageError("--noise-target (render.noise_target) with --spp-range or --pixel-bounds: each shard or tile would "
                     "stop at its own noise, and the pieces would not merge; render the whole film");
  if ((a.checkpoint > 0 || a.resume) && (several || set.guiding))
    throw UsageError("--checkpoint and --resume work with one device and no --mpi or guiding");
  if (set.noise_target <= 0 && a.checkpoint <= 0 && !a.resume && (a.preview.empty() || several)) return nullptr;
  WatchConfig c;
  c.noise_target = set.noise_target;
  c.preview = a.preview;
  c.image = output;
  c.checkpoint_seconds = a.checkpoint;
  c.state_path = film_state_path(output);
  c.id = render_identity(set);
  c.exr = exr_options(a.half, a.compression, scene.film);
  c.meta["scene"] = scene.path;
  c.meta["spp_requested"] = set.spp;
  c.spp = set.spp;
  if (a.checkpoint > 0 || a.resume) {
    c.id.scene_hash = hash();
    c.state_key = film_state_key(c.id, set.window, set.sample_begin, set.spp);
  }
  auto w = std::make_unique<RenderWatch>(std::move(c));
  if (a.resume && !a.quiet && mpi.rank == 0)
    std::cerr << (w->load_resume() ? fmt::format("spectrack: resuming from {} ({} samples done)\n", film_state_path(output),
                                                 w->resume()->samples_done)
                                   : fmt::format("spectrack: no film state {}: rendering from the first sample\n",
                                                 film_state_path(output)));
  else if (a.resume)
    w->load_resume();
  return w;
}

// One render of a loaded scene (one frame of a sequence) to `output`.
int render_scene(const RenderArgs& a, MpiArg& mpi, const SceneDesc& scene, const std::string& output,
                 std::chrono::steady_clock::time_point t0) {
  const bool root = mpi.rank == 0;
  const bool quiet = a.quiet || !root;
  RenderOptions opt = render_options(a, quiet);
  opt.aovs = film_layers(a, scene, output);
  check_half(a.half, scene, output, quiet);  // --half with a PNG: exit 2
  check_tracker_scheme(scene, opt, a.scheme, a.tracker);  // --scheme with a tracker that ignores it: exit 2
  const RenderSettings set = resolve_settings(scene, opt);
  const double time_limit = a.time_limit > 0 ? a.time_limit : scene.render.time_limit;
  loop_started_flag()->store(false);  // this frame's loop: until it starts, a signal ends the process at once
  if (time_limit > 0) {
    opt.deadline = t0 + std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(time_limit));
    if (std::chrono::steady_clock::now() >= *opt.deadline)  // spent before this frame's set-up began
      throw TimeLimitError(time_limit_message(deadline_watch().context(), time_limit, phase_slot().load()));
    deadline_watch().arm(*opt.deadline, time_limit);  // set-up phases: ends the process at the deadline
  }
  set_phase("output checks and device selection");
  check_distinct_paths({{"the image", output}, {"--preview", a.preview}, {"--stats-json", a.stats_json}},
                       scene_inputs(scene));
  if (root) {
    check_output_path(output);
    if (!a.preview.empty()) check_output_path(a.preview);
    if (!a.stats_json.empty()) check_writable_file(a.stats_json);
  }
  std::vector<std::string> devices = parse_device_list(a.device);
  check_chunk_spp(a.chunk_spp, devices, a.device);  // meaningless with one device: exit 2
  if (set.guiding && mpi.on)
    throw UsageError("--mpi: guiding renders in one process for now (each rank would train its own cache); use "
                     "--guiding off");
#ifdef SPECTRACK_HAVE_MPI
  if (mpi.on && devices.size() == 1 && devices[0].empty()) devices[0] = mpi_default_device(mpi.world);
#endif
  // The scene hash reads every VDB and map once more: on the writing rank only, beside the render.
  std::future<std::string> hash;
  if (root) hash = std::async(std::launch::async, [&scene] { return scene_hash(scene); });
  std::string hash_value;
  auto get_hash = [&] {
    if (hash_value.empty()) hash_value = hash.get();
    return hash_value;
  };
  std::unique_ptr<RenderWatch> watch = make_watch(a, mpi, scene, set, devices, output, get_hash);
  opt.watch = watch.get();
  const bool tty = ::isatty(2);
  opt.progress = progress_reporter(quiet, tty, double(process_samples(set, mpi)), 5.0,
                                   watch ? std::function<std::string()>([w = watch.get()] { return w->note(); })
                                         : std::function<std::string()>());
  opt.stop = stop_flag();
  opt.loop_started = loop_started_flag();
  if (!quiet)
    std::cerr << fmt::format("spectrack: {} on {} ({}x{}{}, samples {}:{}, tracker {}, scheme {}{})\n", scene.path,
                             devices.size() == 1 && devices[0].empty() ? select_device("").name : join(devices, ","),
                             scene.film.width, scene.film.height,
                             a.pixel_bounds.empty() ? "" : ", pixels " + a.pixel_bounds, set.sample_begin,
                             set.sample_begin + set.spp, tracker_name(set.tracker), scheme_name(set.scheme),
                             mpi.on ? fmt::format(", {} MPI ranks", mpi.size) : "");
  const double seconds_to_renderer = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  set_phase("renderer set-up");
  MultiDeviceResult r = render_share(scene, opt, set, devices, a.chunk_spp, mpi);
  deadline_watch().disarm();  // the stage loop ran: what it finished is written whatever the time
  if (tty && !quiet) std::fprintf(stderr, "\n");
  const bool signalled = stop_flag()->load();
  if (!root) return signalled || (r.piece.interrupted && !r.time_limit_reached) ? kExitInterrupted : 0;
  if (r.piece.samples() > 0) r.piece.id.scene_hash = get_hash();
  const RenderOutputs out{output, a.preview, a.stats_json, exr_options(a.half, a.compression, scene.film), a.quiet, a.mpi,
                          set.noise_target};
  const RenderTimes times{std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), seconds_to_renderer};
  return finish_render(out, scene, r, times, mpi.size, time_limit, signalled);
}

// A render, or with --frames A:B a sequence: frame patterns (frames.h) in the media's files and
// in the output, preview and statistics names are replaced per frame; every frame's files are
// checked before the first render, and a missing one is named.
int cmd_render(const RenderArgs& a, MpiArg& mpi) {
  const auto t0 = command_start();
  // --time-limit bounds the scene loading too (a scene's render.time_limit is known once it is loaded)
  if (a.time_limit > 0)
    deadline_watch().arm(t0 + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                  std::chrono::duration<double>(a.time_limit)),
                         a.time_limit);
  set_phase("scene loading");
  SceneDesc scene = load_scene(a.scene);
  const std::string output = a.output.empty() ? scene.film.output : a.output;
  check_no_nul(scene, output);
  if (a.frames.empty()) {
    for (const MediumDesc& m : scene.media)
      if (has_frame_pattern(fs::path(m.file).filename().string()))
        throw Error(fmt::format("{}: {}/file: {} is a frame pattern: render it with --frames A:B", scene.path, m.json_path, m.file));
    return render_scene(a, mpi, scene, output, t0);
  }
  long long first = 0, last = 0;
  check_frames(a.frames, &first, &last);  // checked by CLI11 already
  if (!has_frame_pattern(fs::path(output).filename().string()))
    throw Error(fmt::format("--frames {}: the output {} has no frame pattern (e.g. out_####.exr or out_$F4.exr), so "
                            "every frame would overwrite it", a.frames, output));
  set_phase("the frames' file checks");
  check_frame_files(scene, first, last);
  for (long long f = first; f <= last; ++f) {
    SceneDesc frame = scene;
    for (MediumDesc& m : frame.media) m.file = expand_frame(m.file, f);
    RenderArgs fa = a;
    // the majorant hierarchy is compiled in for every frame (an empty frame has none), so that the
    // frames share one kernel build
    if (a.majorant_block > 1) fa.feature_floor = ST_FEATURE_COARSE_MAJORANT;
    fa.preview = expand_frame(a.preview, f);
    fa.stats_json = expand_frame(a.stats_json, f);
    if (!a.quiet && mpi.rank == 0) std::cerr << fmt::format("frame {} ({} of {})\n", f, f - first + 1, last - first + 1);
    deadline_watch().set_context(fmt::format("frame {}: ", f));  // each frame's limit counts from its start
    const int code = render_scene(fa, mpi, frame, expand_frame(output, f),
                                  f == first ? t0 : std::chrono::steady_clock::now());
    if (code != 0) return code;
  }
  return 0;
}

// The `render` subcommand's arguments and flags.
CLI::App* add_render_command(CLI::App& app, RenderArgs& ra) {
  auto* render = app.add_subcommand("render", "render a scene file to EXR or PNG");
  render->add_option("scene", ra.scene, "scene file (spectrack-scene/1 JSON)")->required();
  render->add_option("-o,--output", ra.output, "output image (.exr or .png); default: the scene's film.output");
  auto* o_spp = render->add_option("--spp", ra.spp, "samples per pixel (overrides film.spp)")->check(integer_in(1, 1 << 24));
  render->add_option("--spp-range", ra.spp_range,
                     "render samples A..B-1 of every pixel of the full sequence (a shard; merge with `spectrack merge`)")
      ->check(CLI::Validator(
          [](std::string& v) {
            int64_t a = 0, b = 0;
            return check_spp_range(v, &a, &b);
          },
          "A:B"))
      ->excludes(o_spp);
  render->add_option("--pixel-bounds", ra.pixel_bounds,
                     "render only pixels x0..x1-1, y0..y1-1 of the film (a tile; merge with `spectrack merge`)")
      ->check(CLI::Validator(
          [](std::string& v) {
            std::array<int, 4> b;
            return check_pixel_bounds(v, &b);
          },
          "x0,x1,y0,y1"));
  render->add_option("--frames", ra.frames,
                     "render frames A..B of a sequence: '#' runs or $F<N> in the media's file, the output, preview and "
                     "stats names become the frame number")
      ->check(CLI::Validator(
          [](std::string& v) {
            long long a = 0, b = 0;
            return check_frames(v, &a, &b);
          },
          "A:B"));
  render->add_option("--seed", ra.seed, "random seed (overrides render.seed)")->check(integer_in(0, 4294967295LL));
  render->add_option("--tracker", ra.tracker, "tracker: " + tracker_names())->check(one_of("tracker", tracker_name_list()));
  render->add_option("--scheme", ra.scheme, "spectral scheme (spectral trackers only): " + scheme_names())
      ->check(one_of("scheme", scheme_name_list()));
  render->add_option("--absorption", ra.absorption,
                     "absorption at real collisions (overrides render.absorption): event (ends the path) or weight "
                     "(beta takes the albedo; default for spectral, decomposition, spectral-decomposition, spectral-mis)")
      ->check(one_of("absorption", absorption_name_list()));
  render->add_option("--light-sampling", ra.light_sampling,
                     "lights that next-event estimation samples at each scatter event (overrides "
                     "render.light_sampling): all (one shadow ray to each), uniform (one, each as likely), power (one, "
                     "chosen by power), contribution (one, chosen by its unoccluded contribution at the event) or "
                     "auto (default: contribution in dense media, all in thin ones)")
      ->check(one_of("light sampling", light_sampling_name_list()));
  render->add_option("--transmittance", ra.transmittance,
                     "transmittance estimator of shadow rays (overrides render.transmittance): ratio ((residual) ratio "
                     "tracking) or ray-marching (the unbiased ray-marching estimator of Kettunen et al. 2021)")
      ->check(one_of("transmittance", transmittance_name_list()));
  render->add_option("--lookup", ra.lookup,
                     "how density lookups read a VDB grid (overrides render.lookup): trilinear (the blend of the 8 "
                     "voxels around the point; default) or stochastic (one of them, chosen with its trilinear weight: "
                     "the same expectation, cheaper lookups, more noise)")
      ->check(one_of("lookup", lookup_name_list()));
  render->add_option("--guiding", ra.guiding,
                     "volume path guiding (overrides render.guiding): on (training passes learn a radiance cache, "
                     "scattered directions follow it), off, or auto (default; off until measurements say where it pays)")
      ->check(one_of("guiding", {"off", "on", "auto"}));
  render->add_flag("--spectral", ra.spectral,
                   "spectral mode (overrides render.color): each path carries three wavelengths, colours become smooth "
                   "spectra (Jakob and Hanika 2019), the film turns them into linear sRGB (docs/spectral.md)");
  render->add_option("--march-spacing", ra.march_spacing,
                     "ray-marching transmittance: majorant optical depth between the samples of one estimate (default 1)")
      ->check(finite_range(1e-3, 1e3));
  render->add_option("--pilot-spacing", ra.pilot_spacing,
                     "ray-marching transmittance: majorant optical depth between the pilot's samples (default 2)")
      ->check(finite_range(1e-3, 1e3));
  render->add_option("--device", ra.device,
                     "OpenCL device: P:D or a name substring, 'all', or a comma-separated list to share the samples "
                     "(env SPECTRACK_DEVICE)")
      ->check(not_blank("device"));
  render->add_option("--chunk-spp", ra.chunk_spp, "samples per pixel a device takes at a time with several devices")
      ->check(integer_in(1, 1 << 24));
  render->add_flag("--mpi", ra.mpi, "under mpirun: each rank renders a disjoint sample range, rank 0 writes the image");
  render->add_option("--stats-json", ra.stats_json, "write render statistics as JSON");
  render->add_option("--preview", ra.preview,
                     "also write a PNG preview, rewritten every few seconds during the render (one device, no --mpi)")
      ->check(png_file());
  render->add_option("--path-slots", ra.path_slots, "paths in flight (default: 65536 on CPUs, 1M on GPUs)")->check(integer_in(1, 1 << 24));
  render->add_option("--budget", ra.budget, "tracking iterations per path and kernel launch")->check(integer_in(1, 1 << 20));
  render->add_option("--majorant-cell", ra.majorant_cell,
                     "voxels per fine majorant-cell edge (0: automatic, 2 voxels or coarser for huge grids)")
      ->check(integer_in(0, 1024))
      ->capture_default_str();
  render->add_option("--majorant-block", ra.majorant_block,
                     "fine cells per block edge of the adaptive majorant hierarchy, each block walked whole or "
                     "refined by a cost model (0 or 1: one level, every fine cell walked)")
      ->check(integer_in(0, 1024))
      ->capture_default_str();
  render->add_option("--majorant-step-cost", ra.majorant_step_cost,
                     "the majorant hierarchy's cost model: one DDA step in density lookups; lower refines more, "
                     "higher walks more blocks whole (default -1: automatic, 0.6, or 2 for spectral-decomposition)")
      ->check(finite_range(-1.0, 1e6))
      ->capture_default_str();
  render->add_option("--batches-in-flight", ra.batches_in_flight,
                     "batches of samples in flight, 1-" + std::to_string(ST_MAX_BATCHES_IN_FLIGHT) + " (default: the maximum)")
      ->check(integer_in(1, ST_MAX_BATCHES_IN_FLIGHT));
  render->add_option("--shadow-ring", ra.shadow_ring,
                     "shadow-ray entries per path and light, 1-" + std::to_string(ST_MAX_SHADOW_RING) +
                         ": a path scatters again while the shadow rays of its last N-1 bounces run (default 2; "
                         "the image is the same)")
      ->check(integer_in(1, ST_MAX_SHADOW_RING));
  render->add_option("--time-limit", ra.time_limit,
                     "stop cleanly after this many seconds from the start (the finished samples are written, "
                     "exit 0; if none finished, nothing is written, exit 3; overrides render.time_limit)")
      ->check(finite_range(1e-3, 1e9));
  render->add_option("--noise-target", ra.noise_target,
                     "stop once the image's relative error (the 95th percentile over its noisy pixels of the standard "
                     "error over the mean, from the variance layer; docs/cli.md) is at or below this, or at --spp or "
                     "the time limit (overrides render.noise_target; adds the variance layer)")
      ->check(finite_range(1e-6, 1.0));
  render->add_option("--checkpoint", ra.checkpoint,
                     "every this many seconds, and when the render ends early, write the image and its film state "
                     "(OUTPUT.resume), which --resume continues from")
      ->check(finite_range(0.1, 1e9));
  render->add_flag("--resume", ra.resume,
                   "continue from OUTPUT.resume (a checkpoint) if it exists: the final sums equal the uninterrupted "
                   "render's, bit for bit");
  render->add_flag("--alpha", ra.alpha,
                   "write A = 1 - the camera ray's transmittance (and AR, AG, AB) with a transparent, premultiplied "
                   "R, G, B; the environment seen straight from the camera goes to the environment layer (default for "
                   "EXR outputs; film.alpha)");
  render->add_flag("--no-alpha", ra.no_alpha, "no alpha: R, G, B hold the whole image, background included");
  render->add_option("--aov", ra.aov,
                     "film layers to add, comma-separated: " + aov_names() +
                         " (film.aovs; docs/aov.md; EXR outputs only)");
  render->add_flag("--half", ra.half, "16-bit half-float EXR channels (film.half; such files cannot be merged)");
  render->add_option("--compression", ra.compression, "EXR compression (film.compression; default zip)")
      ->check(one_of("compression", exr_compressions()));
  render->add_flag("--generic-kernels", ra.generic_kernels, "use the generic kernels instead of ones specialised to the scene");
  render->add_flag("-q,--quiet", ra.quiet, "no progress output");
  return render;
}

}  // namespace

int main(int argc, char** argv) {
  install_signal_handlers();  // first: a signal in any phase ends the command with 130, never by the signal
  CLI::App app{"spectrack: spectral and decomposition tracking for heterogeneous volumes on OpenCL"};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string("spectrack ") + SPECTRACK_VERSION);
  RenderArgs ra;
  add_render_command(app, ra);
  MergeArgs ma;
  add_merge_command(app, ma);
  app.add_subcommand("devices", "list OpenCL platforms and devices");
  std::vector<std::string> info_files;
  bool info_json = false;
  auto* info = app.add_subcommand("info", "print the grids of VDB/NanoVDB files and the media, lights and camera of scenes");
  info->add_option("files", info_files, "volume (.vdb, .nvdb) or scene (.json) files")->required()->expected(1, -1);
  info->add_flag("--json", info_json, "one JSON document instead of tables");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  MpiArg mpi;
  try {
    if (app.got_subcommand("devices")) return cmd_devices();
    if (app.got_subcommand("merge")) return cmd_merge(ma);
    if (app.got_subcommand("info")) return cmd_info(info_files, info_json);
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
  } catch (const TimeLimitError& e) {
    std::cerr << "error: " << e.what() << "\n";
#ifdef SPECTRACK_HAVE_MPI
    if (mpi.on) mpi_finish();
#endif
    return kExitTimeLimit;
  } catch (const UsageError& e) {
    std::cerr << "error: " << e.what() << "\n";
#ifdef SPECTRACK_HAVE_MPI
    if (mpi.on && mpi.size > 1) mpi_abort(2);
    if (mpi.on) mpi_finish();
#endif
    return 2;
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
