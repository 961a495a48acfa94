// settings.h: what a render is asked for and what it resolves to.
//
// Design (pbrt-v4's PBRTOptions pattern): RenderOptions holds the caller's overrides of the scene
// (command line, tests, benchmarks, Python), each one std::optional so "not given" is not a
// sentinel value; its estimator choices are numbers of the enum tables of kernels/types.h, as
// those callers give them. resolve_settings() combines them with the scene once, checks them
// against the scene and the film, and returns typed RenderSettings (enums for every choice;
// tracker, scheme, seed, samples, pixel window, channels per sample). Every consumer (Renderer, the render identity of a film piece, the
// multi-device and MPI drivers, the CLI) takes the resolved settings; nothing else re-derives them.
// An `auto` choice is recorded twice, as requested and as used: light_sampling and
// light_sampling_used (RenderResult, resolved by the scene packer), guiding_requested and
// guiding (resolved here; the statistics' guiding and guiding_used).
#pragma once
#include <array>
#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "kernels/guiding.h"  // st_guide_record (the records hook)
#include "scene/scene.h"

namespace spectrack {

struct GuideCache;  // guiding/guide_cache.h
class FilmWatch;   // integrator/film_watch.h

// Light sampling of next-event estimation when neither the command line nor the scene chooses
// (bench/RESULTS.md, "One light per scatter event" and "Light sampling by contribution").
constexpr st_light_sampling kDefaultLightSampling = ST_LIGHT_SAMPLING_AUTO;
// Light sampling "auto" (types.h) picks "contribution" when the scene's media make a shadow ray
// crossing them take at least this many density lookups (the residual majorant's optical depth
// along the mean chord of each medium's box, summed over media: MajorantInfo::chord_lookups), and
// "all" below. bench/RESULTS.md "Light sampling by contribution": the bench scenes' values and
// where one shadow ray per event starts to pay.
constexpr double kAutoContributionLookups = 2.0;
// Equi-angular sampling (docs/equiangular.md) when neither the command line nor the scene chooses,
// and the rule of its "auto": on while the media's mean majorant optical depth along the mean chord
// of their boxes (summed over media) is below kAutoEquiangularDepth (bench/RESULTS.md,
// "Equi-angular sampling": where it pays and where it does not).
constexpr EquiangularMode kDefaultEquiangular = kEquiangularOff;
constexpr double kAutoEquiangularDepth = 1.0;
// Transmittance estimator of shadow rays when neither the command line nor the scene chooses, and
// the ray-marching spacings (majorant optical depth between samples; bench/RESULTS.md,
// "Ray-marching transmittance").
constexpr st_transmittance_mode kDefaultTransmittance = ST_TRANSMITTANCE_RATIO;
constexpr double kDefaultMarchSpacing = 1.0;
constexpr double kDefaultPilotSpacing = 2.0;
// Density lookups when neither the command line nor the scene chooses (bench/RESULTS.md,
// "Stochastic one-voxel lookups": on PoCL the variance it adds outweighs the time it saves).
constexpr st_lookup_mode kDefaultLookup = ST_LOOKUP_TRILINEAR;
// Spectral mode's wavelengths when neither the command line nor the scene chooses (docs/spectral.md,
// "Stratified wavelengths"; bench/RESULTS.md's rows of 2026-12-08: the same expectation, 1.1-4.5x
// less variance at the same cost).
constexpr st_wavelength_sampling kDefaultWavelengthSampling = ST_WAVELENGTHS_STRATIFIED;
// Shadow-ray entries per (path, light) (types.h; bench/RESULTS.md, "No waiting paths").
constexpr int kDefaultShadowRing = 2;
// Tentative collisions + DDA steps per item and kernel launch (unfinished items are re-queued).
constexpr int kDefaultIterationBudget = 256;
// Paths in flight by device type (batch_plan.cpp).
constexpr int kDefaultPathSlotsCpu = 1 << 16, kDefaultPathSlotsGpu = 1 << 20;
// Fine cells per block edge of the adaptive majorant hierarchy (docs/majorant-hierarchy.md).
constexpr int kDefaultMajorantBlock = 8;
// The hierarchy's automatic step cost in density lookups per DDA step (auto_majorant_step_cost,
// scene/pack_media.cpp), and that of spectral trackers that decompose media with a control.
constexpr double kMajorantStepCost = 0.6, kMajorantStepCostControl = 2.0;

struct RenderOptions {
  std::optional<int> spp;               // samples per pixel (else film.spp)
  int64_t sample_begin = 0;             // first sample index of the full sequence (sample-range shards)
  // The samples are one shard's range of a longer render (--spp-range, Python's spp_range): with
  // guiding it holds all of the training pass's samples or none (RenderSettings::guide_training_samples).
  bool sample_range = false;
  // Pixel window x0, x1, y0, y1 (x1, y1 exclusive, pbrt's --pixelbounds); else the whole film.
  std::optional<std::array<int, 4>> pixel_bounds;
  std::optional<int64_t> seed;          // else render.seed
  std::optional<int> tracker;           // st_tracker, else render.tracker
  std::optional<int> scheme;            // st_scheme, else render.spectral_scheme
  std::optional<int> absorption;        // st_absorption, else render.absorption, else the tracker's default
  std::optional<int> light_sampling;    // st_light_sampling, else render.light_sampling, else kDefaultLightSampling
  std::optional<int> transmittance;     // st_transmittance_mode, else render.transmittance, else kDefaultTransmittance
  std::optional<double> march_spacing;  // ray marching: majorant optical depth between samples (kDefaultMarchSpacing)
  std::optional<double> pilot_spacing;  // ray marching: the same for the pilot (kDefaultPilotSpacing)
  std::optional<int> lookup;            // st_lookup_mode, else render.lookup, else kDefaultLookup
  std::optional<int> color;             // st_film_color, else render.color (--spectral)
  std::optional<int> wavelength_sampling;  // st_wavelength_sampling, else render.wavelength_sampling, else the default
  std::optional<uint32_t> aovs;         // film layers, ST_AOV_BIT bits; else film.aovs (+ alpha if film.alpha)
  std::optional<int> guiding;           // GuidingMode (scene.h), else render.guiding, else auto
  std::optional<int> equiangular;       // EquiangularMode (scene.h), else render.equiangular, else kDefaultEquiangular
  std::optional<std::array<double, 2>> shutter;  // [open, close] seconds (--shutter), else camera.shutter
  // Testing: called with the guide cache after every training pass's fit, before its upload (a
  // deliberately wrong cache must still give an unbiased image).
  std::function<void(GuideCache&)> guide_cache_hook;
  // Testing: called with every training pass's records, before the fit.
  std::function<void(const std::vector<st_guide_record>&)> guide_records_hook;
  // The camera samples of a training pass that make records, at most (guide_cache.h
  // kGuideRecordSamples; 0: every one); < 0: guide_record_samples_setting().
  int64_t guide_record_samples = -1;
  int guide_grid_cells = 0;             // guide regions along the media box's longest axis; 0: kGuideGridCells
  int guide_depth = 0;                  // guided scatter events: depth below this; 0: guide_depth_setting's default, < 0: all
  float guide_alpha = -1.0f;            // the fitted regions' selection probability; < 0: guide_alpha_setting (learned)
  // guided roulette and splitting (guide_cache.h) where given; else on with --guiding on and off
  // where auto turns guiding on; "on" needs guiding
  std::optional<bool> guide_splitting;
  // With guiding: the trained cache's file (--guide-cache): read where it exists (no training), else
  // written after training, so that every part of a render uses one cache (guide_cache_file.h)
  std::string guide_cache_file;
  std::string scene_json;  // the JSON a scene made in memory was parsed from (its hash: guide_cache_key), else ""
  bool film_state = false;              // --checkpoint or --resume: a film state holds no guide (auto: guiding off)
  std::string device;                   // "P:D", name substring, or "" (SPECTRACK_DEVICE, then default)
  std::optional<int> path_slots;        // paths in flight; else by device type (kDefaultPathSlotsCpu/Gpu)
  int iteration_budget = kDefaultIterationBudget;  // tentative collisions + DDA steps per item and launch
  int majorant_cell = 0;                // voxels per fine majorant-cell edge; 0: automatic (2, coarser for huge grids)
  int majorant_block = kDefaultMajorantBlock;  // fine cells per block edge of the majorant hierarchy; 0 or 1: one level
  std::optional<double> majorant_step_cost;  // the hierarchy's cost model: one DDA step, in density lookups; else automatic
  bool generic_kernels = false;         // the generic kernel (every feature) instead of one specialised to the scene
  std::optional<int> batches_in_flight;  // batch result buffers in the ring (else ST_MAX_BATCHES_IN_FLIGHT)
  std::optional<int> shadow_ring;       // shadow-ray entries per (path, light), 1..ST_MAX_SHADOW_RING (types.h); else kDefaultShadowRing
  // st_feature bits compiled in whatever the scene needs (a kernel with more features renders the
  // same image): a frame sequence asks for the bits that depend on a frame's grid data, so every
  // frame uses the one kernel build
  uint32_t feature_floor = 0;
  bool quiet = false;
  std::function<void(double)> progress;     // fraction of samples done
  // Set asynchronously to stop: the stage loop ends at its next iteration and the result holds
  // the batches finished by then (RenderResult::interrupted).
  const std::atomic<bool>* stop = nullptr;
  // Stop the same way once this time has come (--time-limit, render.time_limit).
  std::optional<std::chrono::steady_clock::time_point> deadline;
  // Set to true when a stage loop starts (from then on a stop has finished samples to save).
  std::atomic<bool>* loop_started = nullptr;
  // Relative error at which to stop (integrator/noise.h), else render.noise_target; 0: none. Adds the
  // variance layer, which the error is measured from.
  std::optional<double> noise_target;
  // Adaptive sampling to the noise target (integrator/adaptive.h), else render.adaptive.
  std::optional<bool> adaptive;
  // Looks at the film during the stage loop: stops it at a noise target, writes previews and
  // checkpoints, resumes from a checkpoint (integrator/film_watch.h); not owned.
  FilmWatch* watch = nullptr;
};

// A pixel window of the film: pixels x0 .. x0 + width - 1, y0 .. y0 + height - 1.
struct FilmWindow {
  int x0 = 0, y0 = 0, width = 0, height = 0;
  int x1() const { return x0 + width; }
  int y1() const { return y0 + height; }
  uint64_t pixels() const { return uint64_t(width) * uint64_t(height); }
};

struct RenderSettings {
  st_tracker tracker{};
  st_scheme scheme{};
  st_absorption absorption{};
  st_light_sampling light_sampling{};  // as requested (auto: resolved by the scene packer, RenderResult)
  st_transmittance_mode transmittance{};
  double march_spacing = kDefaultMarchSpacing, pilot_spacing = kDefaultPilotSpacing;  // ray marching
  st_lookup_mode lookup{};
  st_film_color color{};
  st_wavelength_sampling wavelength_sampling = kDefaultWavelengthSampling;  // spectral mode's wavelengths
  uint32_t aovs = 0;            // film layers (ST_AOV_BIT bits; alpha implies environment)
  uint32_t seed = 0;
  int spp = 0;                  // samples per pixel to render
  int64_t sample_begin = 0;     // samples sample_begin .. sample_begin + spp - 1
  FilmWindow window;            // the pixels rendered
  int full_width = 0, full_height = 0;  // the film
  int channels_per_sample = 1;  // paths per (pixel, sample): the per-channel trackers' lanes (st_paths_per_sample)
  GuidingMode guiding_requested = kGuidingAuto;  // as asked for (scene.h: off, on, auto)
  bool guiding = false;         // volume path guiding on: guiding_requested resolved (auto: guiding_pays)
  EquiangularMode equiangular = kDefaultEquiangular;  // as asked for (the scene packer resolves auto)
  bool guide_splitting = false;  // with guiding: guided roulette and splitting (RenderOptions::guide_splitting)
  // With guiding, samples 0 .. guide_training_samples - 1 of the sequence are the training passes'
  // (random streams of their own, over the full film) and sample i >= guide_training_samples is the
  // render's own sample i - guide_training_samples (docs/guiding.md, "Determinism across shards"):
  // every part of a render (shard, tile, device, MPI rank) trains the same cache and keeps the
  // training samples only if its range holds all of them. 0 without guiding.
  int guide_training_samples = 0;
  // The shutter [open, close] in seconds (none: every path at time 0); the paths' times are
  // stratified over film.spp samples (the scene's, so every shard of a render has the same times)
  std::optional<std::array<double, 2>> shutter;
  int time_strata = 1;
  double noise_target = 0;      // relative error at which the render stops (integrator/noise.h); 0: none
  bool adaptive = false;        // adaptive sampling to the noise target (integrator/adaptive.h)
  // The iteration budget and the majorant grid's choices (RenderOptions): they change which random
  // numbers a sample draws, so a film records them (film.h RenderIdentity) and the packer reads them here
  int iteration_budget = kDefaultIterationBudget;
  int majorant_cell = 0, majorant_block = kDefaultMajorantBlock;
  std::optional<double> majorant_step_cost;
};

// A boundary between two parts of a render's samples (MPI ranks, device chunks) that keeps the
// guide's training samples 0 .. guide_training_samples - 1 in one part: one inside them moves to
// their end.
inline int64_t guide_part_boundary(const RenderSettings& s, int64_t b) {
  return b > 0 && b < s.guide_training_samples ? int64_t(s.guide_training_samples) : b;
}

// What a result records of the settings it was rendered with: the estimator choices and the seed
// (RenderResult, MultiDeviceResult; film identities and stats are made from these).
struct RenderChoices {
  st_tracker tracker{};
  st_scheme scheme{};
  st_absorption absorption{};
  st_light_sampling light_sampling{};  // as requested (RenderResult::light_sampling_used: as run)
  st_transmittance_mode transmittance{};
  st_lookup_mode lookup{};
  st_film_color color{};
  uint32_t aovs = 0;            // film layers (ST_AOV_BIT bits)
  uint32_t seed = 0;
  GuidingMode guiding_requested = kGuidingAuto;  // as asked for (whether guiding ran: GuideInfo::used)
  double noise_target = 0;  // the relative error the render stops at; 0: none

  void record_settings(const RenderSettings& s) {
    noise_target = s.noise_target;
    guiding_requested = s.guiding_requested;
    aovs = s.aovs;
    tracker = s.tracker;
    scheme = s.scheme;
    absorption = s.absorption;
    light_sampling = s.light_sampling;
    transmittance = s.transmittance;
    lookup = s.lookup;
    color = s.color;
    seed = s.seed;
  }
};

// Throws Error naming the scene file and field (or the option) when the options do not fit the
// scene: pixel bounds outside the film, a tracker that needs achromatic media on chromatic ones,
// an empty or out-of-range sample range.
RenderSettings resolve_settings(const SceneDesc& scene, const RenderOptions& options);

// Whether `--guiding auto` turns guiding on for the scene (docs/guiding.md "What auto does"): a
// medium that emits and does not scatter (a lamp, whose light next-event estimation does not
// sample) beside a medium that scatters, and no medium that both scatters and emits (fire in its
// smoke, whose emission every path through it gathers: guiding measured no gain there).
bool guiding_pays(const SceneDesc& scene);

// One VDB medium's majorant structure, for the render statistics.
struct MajorantInfo {
  int cell = 0;                 // voxels per fine-cell edge
  int block = 0;                // fine cells per block edge (0: one level, every cell stored)
  size_t fine_cells = 0;        // cells of the fine grid over the medium's box
  size_t blocks_empty = 0, blocks_whole = 0, blocks_refined = 0;
  std::vector<int> levels;               // group edges (fine cells) of the hierarchy, finest first
  std::vector<size_t> blocks_per_level;  // blocks walked at each level
  size_t bytes = 0;             // device memory of the structure
  double step_cost = 0;         // the cost model's DDA step in density lookups, as used (--majorant-step-cost or automatic)
  double seconds_build = 0;
  // density lookups of a ratio-tracking shadow ray along the mean chord of the medium's box (4 V /
  // S, Cauchy): the mean residual majorant over the fine cells times that length (light sampling
  // "auto", kAutoContributionLookups)
  double chord_lookups = 0;
};

}  // namespace spectrack
