// renderer.h: a scene on one OpenCL device, and the wavefront scheduler that renders it.
//
// Construction does all set-up (settings resolved once, device choice, scene packing with VDB
// loading and majorant grids, kernel build, uploads) so render() only runs the stage loop. The
// loop keeps Q path slots in flight: each iteration launches raygen (refill free slots), track,
// escape, scatter, shadow and finish on the queues the previous iteration filled, then reads every
// queue size and statistic counter in one copy. Samples are organised in batches of whole samples
// per pixel; a batch's results are added to the film (in a fixed order) once all its paths are
// done, and up to ST_MAX_BATCHES_IN_FLIGHT batches are in flight (a ring of result buffers) so
// that a batch's longest paths do not leave the slots idle. A stop request (Ctrl-C) or the
// deadline (--time-limit) ends the loop at its next iteration, with the finished batches on the
// film.
#pragma once
#include <array>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "integrator/settings.h"
#include "scene/scene.h"

namespace spectrack {

struct KernelTime {
  double seconds = 0;
  uint64_t launches = 0;
};

// Statistics the host counts itself (the device's are ST_SUM_COUNTERS of kernels/types.h):
// X(RenderStats field, --stats-json key).
#define ST_HOST_COUNTERS(X)    \
  X(paths, "paths")            \
  X(iterations, "iterations")  \
  X(iterations_below_half, "iterations_below_half_occupancy") \
  X(host_waits, "host_waits")

struct RenderStats {
  // Adds another shard's statistics (counters summed, max_throughput maxed, kernel times summed).
  void add(const RenderStats& o);
  // Every counter with its --stats-json key: the one list that add() and stats_json.cpp use.
  using Counter = uint64_t RenderStats::*;
  static const std::vector<std::pair<const char*, Counter>>& counters();
#define ST_X_DEVICE_STAT(E, field, key) uint64_t field = 0;
#define ST_X_HOST_STAT(field, key) uint64_t field = 0;
  ST_SUM_COUNTERS(ST_X_DEVICE_STAT)
  ST_HOST_COUNTERS(ST_X_HOST_STAT)  // iterations_below_half: iterations with fewer than half the slots busy
  double max_throughput = 0;
  // work distribution: paths in flight (all queues but FREE) over the slots, per iteration
  double occupancy_mean = 0, occupancy_min = 0;
  std::map<std::string, KernelTime> kernels;
};

// Volume path guiding in a render (docs/guiding.md): whether it ran, its cache and its training.
struct GuideInfo {
  bool used = false;
  size_t bytes = 0;           // device memory of the cache
  int regions = 0, regions_guided = 0;  // regions (the cells' kd-tree leaves), and those whose fit guides (alpha > 0)
  int training_passes = 0;
  uint64_t records = 0;       // radiance records of the last training pass
  double seconds_training = 0;  // part of seconds_render
  // where the training time goes: the passes' stage loops (kernels, host loop and record drains),
  // the drains alone (host reads of the records), and the host's refinement, fit and upload
  double seconds_training_loops = 0, seconds_drain = 0, seconds_fit = 0;
  double cpu_seconds_training = 0;  // the process's CPU time (every thread: the device's too on a CPU) in training
  uint64_t training_iterations = 0;  // stage-loop iterations of the passes (each a kernel sequence and a read)
  uint64_t drains = 0;               // host reads of the record buffer
  std::map<std::string, KernelTime> training_kernels;  // the passes' kernel profile, summed
  std::string cache_file;  // --guide-cache: "read" (no training), "written", or empty
};

// What a render ran with where its settings leave the choice to the scene or the device: recorded
// as used, beside RenderChoices' as requested (the EXR metadata and the statistics). A
// multi-device render takes the first device's (path slots and the shadow ring follow each
// device's type and memory; the rest is the same on every device).
struct RunChoices {
  uint32_t features = 0;          // st_feature mask the kernels were compiled for (ST_FEATURES_ALL: generic)
  st_light_sampling light_sampling_used{};  // the kernels' (light_sampling "auto" resolved: scene_pack.cpp)
  bool equiangular_used = false;  // equi-angular samples towards local lights ran ("auto" resolved: pack_lights.cpp)
  std::vector<MajorantInfo> majorants;      // each VDB medium's majorant structure
  GuideInfo guide;                // volume path guiding (its training time is in seconds_render)
  uint64_t path_slots = 0;        // paths in flight (--path-slots, else by device type: batch_plan.cpp)
  uint64_t shadow_ring = 0;       // shadow-ray entries per (path, light) (1 where the default 2 would not fit)
  std::string state_layout;       // the path state's layout: "aos" or "soa" (state_layout.h)
  uint64_t batches_in_flight = 0;  // result buffers in the ring (capped by the batch count and the device)
  int iteration_budget = 0;       // tracking iterations per path and launch
};

struct RenderResult : RenderChoices, RunChoices {
  int width = 0, height = 0;           // the pixel window rendered
  int full_width = 0, full_height = 0; // the film
  int x0 = 0, y0 = 0;                  // the window's top-left pixel in the film
  std::vector<float> rgb;  // width * height * 3, linear, mean over spp_done samples
  // width * height * 3: the sum of the spp_done samples of each pixel (compensated float sums on
  // the device, read back in double) for combining shards without losing precision
  std::vector<double> sum;
  // The film layers beyond the beauty (settings aovs, docs/aov.md), as sums like `sum`: the
  // channels of aov_sum_channels(aovs), width * height * aov_channels.size() values, pixel-major.
  // With alpha, `sum` and `rgb` are the transparent film's R, G, B: the beauty without the lights
  // at infinity seen straight from the camera, which the environment layer holds (their sum is the
  // whole beauty); without alpha they are the whole beauty.
  std::vector<std::string> aov_channels;
  std::vector<double> aov_sum;
  // adaptive sampling (ST_FEATURE_PIXEL_WORK): per pixel of the render, the density lookups and
  // majorant steps of its paths' tracking and shadow rays (queues.h pixel_work_add); else empty
  std::vector<double> pixel_work;
  int64_t sample_begin = 0;            // samples sample_begin .. sample_begin + spp_done - 1
  int spp_requested = 0, spp_done = 0;
  bool interrupted = false;         // fewer samples done than requested (a stop or the time limit)
  bool time_limit_reached = false;  // stopped by RenderOptions::deadline
  bool noise_target_reached = false;  // stopped by RenderOptions::watch (a noise target met: not interrupted)
  std::string device;
  double seconds_setup = 0, seconds_build = 0, seconds_render = 0;
  double cpu_seconds_render = 0;  // the process's CPU time (all threads) over seconds_render: one device's render
  double seconds_first_pass = 0;  // Renderer construction to the first batch added to the film
  bool kernels_from_cache = false;
  RenderStats stats;
};

// The channels a render with film layers `aovs` (ST_AOV_BIT bits) sums per pixel besides the
// beauty: alpha "AR", "AG", "AB" (1 - T per channel); environment "environment.R", ".G", ".B";
// variance "moment2.R", ".G", ".B" (the beauty's squared samples); the passes "emission.R", ...,
// "direct.R", ..., "indirect.R", ...; albedo "albedo.R", ".G", ".B" and depth "depth.Z" (sums
// over the samples whose camera ray collided) with "collision.fraction" (how many collided; in that
// order). Film pieces hold these sums;
// the EXR writer turns them into the layers users see (film.h).
std::vector<std::string> aov_sum_channels(uint32_t aovs);

struct DeviceScene;

class Renderer {
 public:
  // Settings resolved by the caller (resolve_settings(scene, options), once per render: the CLI,
  // the Python API and the multi-device and adaptive drivers), with the options for what they do
  // not hold (device, tuning, hooks, stop flags).
  Renderer(const SceneDesc& scene, const RenderSettings& settings, const RenderOptions& options);
  // Resolves the settings itself (tests, benchmarks: callers that render once).
  Renderer(const SceneDesc& scene, const RenderOptions& options);
  ~Renderer();
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;

  // Renders the resolved settings' samples.
  RenderResult render();
  // Renders samples [sample_begin, sample_begin + spp) of every window pixel (a shard of the full
  // sequence, e.g. one chunk of a multi-device render). With guiding the range holds all of the
  // training samples or none (settings.h guide_training_samples; Error otherwise).
  RenderResult render(int64_t sample_begin, int spp);
  // Adaptive sampling (settings().adaptive): renders samples [sample_begin, sample_begin + spp) of
  // the listed window pixels only (row-major indices in the window), each entry j shifted by
  // sample_offsets[j] where given (a pixel listed twice with offsets 0 and spp takes 2 spp
  // samples); the result's sums (and rgb, aov_sum, pixel_work) hold the entries in list order.
  RenderResult render_pixels(const std::vector<uint32_t>& window_pixels, int64_t sample_begin, int spp,
                             const std::vector<uint32_t>& sample_offsets = {});

  const std::string& device_name() const;
  uint32_t features() const;  // the kernels' st_feature mask
  const SceneDesc& scene() const;
  const RenderSettings& settings() const;
  // The scene as uploaded to the device (for the test probes of device/probe.h).
  DeviceScene& device_scene();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace spectrack
