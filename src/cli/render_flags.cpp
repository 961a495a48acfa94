// render_flags.cpp: the flags of `spectrack render`, in three groups: what is rendered (scene,
// output, samples, window, frames, seed), how it is estimated (tracker, scheme, absorption, light
// sampling, transmittance, lookup, guiding, spectral) and how it runs (devices, outputs besides
// the image, tuning, film layers). Each flag's help is its documentation (docs/cli.md repeats
// every one; DocsCli.EveryHelpFlagIsInCliMd keeps the two equal).
#include <array>
#include <cstdint>
#include <string>

#include "cli/checks.h"
#include "cli/options.h"
#include "cli/render.h"
#include "film/film.h"
#include "integrator/renderer.h"
#include "scene/scene.h"

namespace spectrack {
namespace {

// What is rendered: the scene, the output, the samples, the pixel window, the frames and the seed.
void add_what_flags(CLI::App* render, RenderArgs& ra) {
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
      ->check(frames_check());
  render->add_option("--shutter", ra.shutter,
                     "the shutter's open and close in seconds relative to the frame (overrides camera.shutter): each "
                     "sample's time is drawn in it")
      ->check(CLI::Validator(
          [](std::string& v) {
            std::array<double, 2> s{};
            return check_shutter(v, &s);
          },
          "OPEN:CLOSE"));
  render->add_option("--seed", ra.seed, "random seed (overrides render.seed)")->check(integer_in(0, 4294967295LL));
}

// How the image is estimated: tracker, spectral scheme, absorption, light sampling, transmittance, lookup, guiding, spectral mode.
void add_estimator_flags(CLI::App* render, RenderArgs& ra) {
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
  render->add_option("--guide-splitting", ra.guide_splitting,
                     "with guiding on: guided Russian roulette and splitting of paths by their expected contribution "
                     "against the pixel's estimate from the training passes (on, the default; off: the throughput's "
                     "roulette alone)")
      ->check(one_of("guide-splitting", {"off", "on"}));
  render->add_flag("--spectral", ra.spectral,
                   "spectral mode (overrides render.color): each path carries three wavelengths, colours become smooth "
                   "spectra (Jakob and Hanika 2019), the film turns them into linear sRGB (docs/spectral.md)");
  render->add_option("--march-spacing", ra.march_spacing,
                     "ray-marching transmittance: majorant optical depth between the samples of one estimate (default 1)")
      ->check(finite_range(1e-3, 1e3));
  render->add_option("--pilot-spacing", ra.pilot_spacing,
                     "ray-marching transmittance: majorant optical depth between the pilot's samples (default 2)")
      ->check(finite_range(1e-3, 1e3));
}

// How the render runs: devices, MPI, statistics and preview files, tuning, film layers, quiet.
void add_run_flags(CLI::App* render, RenderArgs& ra) {
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
}

}  // namespace

CLI::App* add_render_command(CLI::App& app, RenderArgs& ra) {
  auto* render = app.add_subcommand("render", "render a scene file to EXR or PNG");
  add_what_flags(render, ra);
  add_estimator_flags(render, ra);
  add_run_flags(render, ra);
  return render;
}

}  // namespace spectrack
