// render.cpp: `spectrack render`: the command line's overrides of the scene (RenderOptions, once),
// the film layers and EXR options of the output, this process's share of the samples (several
// devices, MPI ranks) and the render of one scene or of a frame sequence, then its files
// (render_outputs.h). A render is a FilmPiece (film/film.h): the window and sample range it holds,
// with exact per-pixel sums; shards, tiles, devices and MPI ranks all combine through merge_pieces.
#include "cli/render.h"

#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <fmt/ranges.h>

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
#include <vector>
#include <iostream>
#include <unistd.h>

#include "cli/checks.h"
#include "cli/options.h"
#include "device/opencl.h"
#include "cli/progress.h"
#include "cli/render_outputs.h"
#include "integrator/render_watch.h"
#include "cli/run_control.h"
#include "image/denoise.h"
#include "image/image.h"
#include "film/film.h"
#include "integrator/multi_device.h"
#include "integrator/renderer.h"
#include "scene/frames.h"
#include "scene/framing.h"
#include "scene/sequence_camera.h"
#include "scene/scene.h"
#include "util/strings.h"
#include "util/warning.h"

namespace fs = std::filesystem;

namespace spectrack {
namespace {

// The command line's overrides of the scene (the flags CLI11 has already range-checked).
RenderOptions render_options(const RenderArgs& a, bool quiet) {
  RenderOptions opt;
  opt.seed = a.seed;
  opt.quiet = quiet;
  opt.path_slots = a.path_slots;
  opt.iteration_budget = a.budget.value_or(opt.iteration_budget);
  opt.majorant_cell = a.majorant_cell.value_or(opt.majorant_cell);
  opt.majorant_block = a.majorant_block.value_or(opt.majorant_block);
  if (a.majorant_step_cost && *a.majorant_step_cost >= 0) opt.majorant_step_cost = a.majorant_step_cost;  // < 0: automatic
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
  if (!a.equiangular.empty()) opt.equiangular = guiding_from_name(a.equiangular);  // checked by CLI11
  if (!a.guide_splitting.empty()) opt.guide_splitting = a.guide_splitting == "on";
  opt.guide_cache_file = a.guide_cache;
  opt.film_state = a.checkpoint || a.resume;
  if (a.spectral) opt.color = ST_FILM_COLOR_SPECTRAL;
  if (!a.wavelength_sampling.empty())  // checked by CLI11
    opt.wavelength_sampling = wavelength_sampling_from_name(a.wavelength_sampling);
  opt.march_spacing = a.march_spacing;
  opt.pilot_spacing = a.pilot_spacing;
  if (!a.absorption.empty()) {
    opt.absorption = absorption_from_name(a.absorption);
    if (*opt.absorption < 0)
      throw Error(fmt::format("--absorption {}: unknown absorption mode (one of: {})", a.absorption, absorption_names()));
  }
  opt.spp = a.spp;
  opt.noise_target = a.noise_target;
  if (a.adaptive) opt.adaptive = true;  // a flag: without it the scene's render.adaptive holds
  if (!a.spp_range.empty()) {
    int64_t b = 0;
    check_spp_range(a.spp_range, &opt.sample_begin, &b);  // checked by CLI11 already
    opt.spp = int(b - opt.sample_begin);
    opt.sample_range = true;
  }
  if (!a.shutter.empty()) {
    std::array<double, 2> shutter{};
    check_shutter(a.shutter, &shutter);  // checked by CLI11 already
    opt.shutter = shutter;
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
  if (mpi.on) std::tie(my_begin, my_end) = mpi_sample_share(mpi.world, set);
#endif
  return std::max<int64_t>(my_end - my_begin, 0);
}

// This process's share of the samples rendered on its devices (an MPI rank with no samples, when
// there are more ranks than samples, contributes an empty piece), reduced to rank 0 under MPI.
MultiDeviceResult render_share(const SceneDesc& scene, const RenderOptions& opt, const RenderSettings& set,
                               const std::vector<std::string>& devices, int chunk_spp, MpiArg& mpi) {
  int64_t my_begin = set.sample_begin, my_end = set.sample_begin + set.spp;
#ifdef SPECTRACK_HAVE_MPI
  if (mpi.on) std::tie(my_begin, my_end) = mpi_sample_share(mpi.world, set);
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

}  // namespace

// The film layers of a render to `output` (docs/aov.md): film.aovs and --aov; alpha from --alpha /
// --no-alpha, else film.alpha, else on for an EXR output. Layers need an EXR (a PNG holds the beauty).
uint32_t film_layers(const RenderArgs& a, const SceneDesc& scene, const std::string& output) {
  uint32_t aovs = scene.film.aovs & ~uint32_t(ST_AOV_BIT(ALPHA));
  std::stringstream list(a.aov);
  std::string name;
  bool alpha_listed = false;
  while (std::getline(list, name, ',')) {
    const int k = aov_from_name(name);
    if (k < 0) throw UsageError(fmt::format("--aov {}: unknown layer '{}' (one of: {})", a.aov, name, aov_names()));
    if (k == ST_AOV_INDEX_ALPHA) alpha_listed = true;
    else aovs |= 1u << k;
  }
  std::string ext = lower_extension(output);
  const bool exr = ext == ".exr";
  if (a.alpha && a.no_alpha) throw UsageError("--alpha and --no-alpha: choose one");
  if (alpha_listed && a.no_alpha) throw UsageError(fmt::format("--aov {} lists alpha, which --no-alpha turns off", a.aov));
  if (a.denoise && !exr)
    throw UsageError(fmt::format("{}: --denoise writes the denoised beauty as an EXR layer: write an EXR", output));
  if (a.denoise) aovs |= ST_AOV_BIT(ALBEDO);  // the denoiser's auxiliary input
  bool alpha = a.alpha || alpha_listed ? true : a.no_alpha ? false : scene.film.alpha.value_or(exr);
  if (!exr && (aovs || ((a.alpha || alpha_listed || scene.film.alpha.value_or(false)) && !a.no_alpha))) {
    std::vector<std::string> from;  // what asked for the layers: the flags, else the scene's fields
    if (!a.aov.empty()) from.push_back("--aov " + a.aov);
    else if (aovs) from.push_back("film.aovs of " + scene.path);
    if (a.alpha) from.push_back("--alpha");
    else if (!alpha_listed && scene.film.alpha.value_or(false) && !a.no_alpha) from.push_back("film.alpha of " + scene.path);
    const std::string why = fmt::format("{}: film layers ({}) need an EXR output; a PNG holds the beauty only (write an EXR "
                                        "and add --preview for a PNG)",
                                        output, fmt::join(from, ", "));
    // the scene's own output and layers: an error of the scene (exit 1); with -o, --aov or --alpha: of the command line
    if (a.output.empty() && a.aov.empty() && !a.alpha) throw Error(fmt::format("{}: /film/output: {}", scene.path, why));
    throw UsageError(why);
  }
  if (!exr) alpha = false;
  return aovs | (alpha ? uint32_t(ST_AOV_BIT(ALPHA)) : 0u);
}

namespace {

ExrOptions exr_options(bool half, const std::string& compression, const FilmDesc& film) {
  ExrOptions o;
  o.half = half || film.half;
  o.compression = compression.empty() ? film.compression : compression;
  return o;
}

// A sequence frame's part of the film's identity: its number, and its camera where the camera was
// framed over the sequence's frames (the framing depends on the frame range: pieces of other ranges differ).
void set_frame_identity(const RenderArgs& a, RenderIdentity& id) {
  if (a.frame) id.frame = std::to_string(*a.frame);
  id.camera = a.framed_camera;
}

// What the watch of a render (integrator/render_watch.h) needs, or nothing when no flag asks for it. It
// looks at one device's film in one process: a noise target, checkpoints and --resume refuse
// several devices and --mpi (exit 2; shards and tiles are refused by resolve_settings, for the
// Python module too); a preview with several devices or ranks is written at the end only.
std::unique_ptr<RenderWatch> make_watch(const RenderArgs& a, const MpiArg& mpi, const SceneDesc& scene,
                                        const RenderSettings& set, const std::vector<std::string>& devices,
                                        const std::string& output, const std::function<std::string()>& hash) {
  const bool several = devices.size() > 1 || mpi.on;
  if (set.noise_target > 0 && several)
    throw UsageError("--noise-target (render.noise_target) stops one device's render at its noise: it does not work "
                     "with several devices or --mpi");
  if ((a.checkpoint || a.resume) && set.adaptive)
    throw UsageError("--checkpoint and --resume do not work with adaptive sampling (a film state holds one sample "
                     "count for every pixel)");
  if (!a.guide_cache.empty() && !a.frames.empty())
    throw UsageError("--guide-cache with --frames: a cache is trained for one frame's media; render the frames "
                     "without it");
  if ((a.checkpoint || a.resume) && (several || set.guiding))
    throw UsageError("--checkpoint and --resume work with one device and no --mpi or guiding");
  if (set.noise_target <= 0 && !a.checkpoint && !a.resume && (a.preview.empty() || several)) return nullptr;
  WatchConfig c;
  c.noise_target = set.noise_target;
  c.preview = a.preview;
  c.image = output;
  c.checkpoint_seconds = a.checkpoint.value_or(0);
  c.state_path = film_state_path(output);
  c.id = render_identity(set);
  set_frame_identity(a, c.id);
  c.exr = exr_options(a.half, a.compression, scene.film);
  c.meta["scene"] = scene.path;
  c.meta["spp_requested"] = set.spp;
  c.spp = set.spp;
  if (a.checkpoint || a.resume) {
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
  check_half(a.half, a.compression, scene, output, a.output.empty(), quiet);  // with a PNG: exit 2, or 1 (the scene's)
  check_piece_storage(!a.spp_range.empty() || !a.pixel_bounds.empty(), exr_options(a.half, a.compression, scene.film),
                      output);
  check_tracker_scheme(scene, opt, a.scheme, a.tracker);  // --scheme with a tracker that ignores it: exit 2
  check_wavelength_sampling(scene, opt, a.wavelength_sampling);  // --wavelength-sampling in rgb mode: exit 2
  const RenderSettings set = resolve_settings(scene, opt);
  const double time_limit = a.time_limit.value_or(scene.render.time_limit);
  loop_started_flag()->store(false);  // this frame's loop: until it starts, a signal ends the process at once
  if (time_limit > 0) {
    opt.deadline = t0 + std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(time_limit));
    if (std::chrono::steady_clock::now() >= *opt.deadline)  // spent before this frame's set-up began
      throw TimeLimitError(time_limit_message(deadline_watch().context(), time_limit, phase_slot().load()));
    deadline_watch().arm(*opt.deadline, time_limit);  // set-up phases: ends the process at the deadline
  }
  if (a.denoise && find_oidn_library().empty()) throw UsageError(denoise_unavailable());
  set_phase("output checks and device selection");
  check_distinct_paths({{"the image", output}, {"--preview", a.preview}, {"--stats-json", a.stats_json},
                        {"--guide-cache", a.guide_cache}},
                       scene_inputs(scene));
  if (root) {
    check_output_path(output);
    if (!a.preview.empty()) check_output_path(a.preview);
    if (!a.stats_json.empty()) check_writable_file(a.stats_json);
  }
  std::vector<std::string> devices = parse_device_list(a.device);
  check_chunk_spp(a.chunk_spp, devices, a.device);  // meaningless with one device: exit 2
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
  MultiDeviceResult r = render_share(scene, opt, set, devices, a.chunk_spp.value_or(0), mpi);  // 0: by device count
  deadline_watch().disarm();  // the stage loop ran: what it finished is written whatever the time
  if (tty && !quiet) std::fprintf(stderr, "\n");
  const bool signalled = stop_flag()->load();
  if (!root) return signalled || (r.piece.interrupted && !r.time_limit_reached) ? kExitInterrupted : 0;
  if (r.piece.samples() > 0) r.piece.id.scene_hash = get_hash();
  set_frame_identity(a, r.piece.id);
  const RenderOutputs out{output, a.preview, a.stats_json, exr_options(a.half, a.compression, scene.film), a.quiet, a.mpi,
                          a.denoise};
  const RenderTimes times{std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), seconds_to_renderer};
  return finish_render(out, scene, r, times, mpi.size, time_limit, signalled);
}

}  // namespace

// A render, or with --frames A:B a sequence: frame patterns (frames.h) in the media's files and
// in the output, preview and statistics names are replaced per frame; every frame's files are
// checked before the first render, and a missing one is named.
int cmd_render(const RenderArgs& a, MpiArg& mpi) {
  const auto t0 = command_start();
  // --time-limit bounds the scene loading too (a scene's render.time_limit is known once it is loaded)
  if (a.time_limit)
    deadline_watch().arm(t0 + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                  std::chrono::duration<double>(*a.time_limit)),
                         *a.time_limit);
  set_warnings_quiet(a.quiet || mpi.rank != 0);  // -q: no warnings (cli.md); under MPI the writing rank warns alone
  set_phase("scene loading");
  SceneDesc scene = load_scene(a.scene);
  const std::string output = a.output.empty() ? scene.film.output : a.output;
  check_no_nul(scene, output);
  if (a.frames.empty()) {
    for (const MediumDesc& m : scene.media)
      if (has_frame_pattern(fs::path(m.file).filename().string()))
        throw UsageError(fmt::format("{}: {}/file: {} is a frame pattern: render it with --frames A:B", scene.path, m.json_path, m.file));
    return render_scene(a, mpi, scene, output, t0);
  }
  long long first = 0, last = 0;
  check_frames(a.frames, &first, &last);  // checked by CLI11 already
  // every file a frame writes is named per frame, or the frames would overwrite one another
  for (const auto& [what, path] : {std::pair<const char*, std::string>{"the output", output}, {"--preview", a.preview},
                                   {"--stats-json", a.stats_json}})
    if (!path.empty() && !has_frame_pattern(fs::path(path).filename().string()))
      throw UsageError(fmt::format("--frames {}: {} {} has no frame pattern (e.g. out_####.exr or out_$F4.exr), so "
                                   "every frame would overwrite it", a.frames, what, path));
  set_phase("the frames' file checks");
  check_frame_files(scene, first, last);
  // one camera for the whole sequence: framing from every frame's boxes (scene/sequence_camera.h)
  set_phase("the sequence's framing");
  const CameraDesc camera = sequence_camera(scene, first, last, a.quiet || mpi.rank != 0).camera;
  for (long long f = first; f <= last; ++f) {
    SceneDesc frame = scene;
    frame.camera = camera;
    for (MediumDesc& m : frame.media) m.file = expand_frame(m.file, f);
    RenderArgs fa = a;
    // the majorant hierarchy is compiled in for every frame (an empty frame has none), so that the
    // frames share one kernel build
    if (a.majorant_block.value_or(RenderOptions().majorant_block) > 1) fa.feature_floor = ST_FEATURE_COARSE_MAJORANT;
    fa.frame = f;
    if (camera_needs_framing(scene.camera)) fa.framed_camera = camera_identity(camera);
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

}  // namespace spectrack
