// renderer.h: a scene on one OpenCL device, and the wavefront scheduler that renders it.
//
// Construction does all set-up (device choice, VDB loading, majorant grids, kernel build,
// uploads) so render() only runs the stage loop. The loop keeps Q path slots in flight: each
// iteration launches raygen (refill free slots), track, escape, scatter, shadow and finish on
// the queues the previous iteration filled, then reads every queue size and statistic counter in
// one copy. Samples are organised in batches of whole samples per pixel; a batch's results are
// added to the film (in a fixed order) once all its paths are done, and up to
// ST_MAX_BATCHES_IN_FLIGHT batches are in flight (a ring of result buffers) so that a batch's
// longest paths do not leave the slots idle. Stopping (Ctrl-C) lets the started batches finish and reports the samples done.
#pragma once
#include <array>
#include <atomic>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "scene/scene.h"

namespace spectrack {

struct RenderOptions {
  int spp = -1;            // overrides film.spp when > 0: the number of samples per pixel
  int64_t sample_begin = 0;  // first sample index of the full sequence (sample-range shards)
  // Pixel window x0, x1, y0, y1 (x1, y1 exclusive, pbrt's --pixelbounds); x1 < 0 = the whole film.
  std::array<int, 4> pixel_bounds{0, -1, 0, -1};
  int64_t seed = -1;       // overrides render.seed when >= 0
  int tracker = -1;        // overrides render.tracker when >= 0
  int scheme = -1;         // overrides render.spectral_scheme when >= 0
  std::string device;      // "P:D", name substring, or "" (SPECTRACK_DEVICE, then default)
  int path_slots = 0;      // paths in flight; 0 = by device type
  int iteration_budget = 256;  // tentative collisions + DDA steps per item and launch
  int majorant_cell = 8;   // voxels per majorant-grid cell edge
  int majorant_block = 4;  // fine cells per coarse-block edge of a two-level majorant grid; 0 or 1 = one level
  bool generic_kernels = false;
  int batches_in_flight = 0;     // batch result buffers in the ring (0: ST_MAX_BATCHES_IN_FLIGHT); 2 = the old scheme  // the generic kernel (every feature) instead of one specialised to the scene
  bool quiet = false;
  std::function<void(double)> progress;        // fraction of samples done
  const std::atomic<bool>* stop = nullptr;     // set asynchronously to stop after started batches
};

struct KernelTime {
  double seconds = 0;
  uint64_t launches = 0;
};

struct RenderStats {
  // Adds another shard's statistics (counters summed, max_throughput maxed, kernel times summed).
  void add(const RenderStats& o);
  // Every counter with its --stats-json key: the one list that add() and stats_json.cpp use.
  using Counter = uint64_t RenderStats::*;
  static const std::vector<std::pair<const char*, Counter>>& counters();
  uint64_t paths = 0;
  uint64_t lookups_track = 0, lookups_shadow = 0, lookups_emission = 0;
  uint64_t real_collisions = 0, null_collisions = 0, control_collisions = 0, residual_collisions = 0;
  uint64_t dda_steps = 0, dda_nonempty = 0, requeues = 0, nonfinite_samples = 0, scatter_events = 0, iterations = 0;
  double max_throughput = 0;
  // work distribution: paths in flight (all queues but FREE) over the slots, per iteration
  double occupancy_mean = 0, occupancy_min = 0;
  uint64_t iterations_below_half = 0;  // iterations with fewer than half the slots busy
  std::map<std::string, KernelTime> kernels;
};

struct RenderResult {
  int width = 0, height = 0;           // the pixel window rendered
  int full_width = 0, full_height = 0; // the film
  int x0 = 0, y0 = 0;                  // the window's top-left pixel in the film
  std::vector<float> rgb;  // width * height * 3, linear, mean over spp_done samples
  // width * height * 3: the sum of the spp_done samples of each pixel (compensated float sums on
  // the device, read back in double) for combining shards without losing precision
  std::vector<double> sum;
  int64_t sample_begin = 0;            // samples sample_begin .. sample_begin + spp_done - 1
  int spp_requested = 0, spp_done = 0;
  bool interrupted = false;
  int tracker = 0, scheme = 0;
  uint32_t seed = 0;
  std::string device;
  double seconds_setup = 0, seconds_build = 0, seconds_render = 0;
  double seconds_first_pass = 0;  // Renderer construction to the first batch added to the film
  bool kernels_from_cache = false;
  uint32_t features = 0;          // st_feature mask the kernels were compiled for (ST_FEATURES_ALL: generic)
  RenderStats stats;
};

class Renderer {
 public:
  Renderer(const SceneDesc& scene, const RenderOptions& options);
  ~Renderer();
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;

  RenderResult render();
  // Renders samples [sample_begin, sample_begin + spp) of every window pixel (a shard of the full
  // sequence); render() is render(options.sample_begin, spp of the options or the scene).
  RenderResult render(int64_t sample_begin, int spp);

  // Probes for tests and benchmarks: the kernels' own device functions on given inputs.
  std::vector<float> probe_density(int medium, const std::vector<std::array<float, 3>>& world_points);
  std::vector<std::array<float, 2>> probe_majorant(int medium, const std::vector<std::array<float, 3>>& world_points);
  // Per item: (t of first real collision or +inf, event, lookups, dda steps); channel -1 = rgb.
  std::vector<std::array<float, 4>> probe_track(std::array<float, 3> o, std::array<float, 3> d, int channel, int n,
                                                std::vector<std::array<float, 4>>* beta = nullptr);
  // Infinite-medium albedo walks from o: per item (sum of scattering weights xyz, max weight) and
  // (absorption score with Le = 1 xyz, escaped flag). channel -1 = rgb.
  void probe_albedo(std::array<float, 3> o, int channel, int n, std::vector<std::array<float, 4>>* scatter,
                    std::vector<std::array<float, 4>>* absorb);
  // Phase sampling around +z: per item (cos theta, pdf, phase value, |wi| - 1).
  std::vector<std::array<float, 4>> probe_phase(int type, float g, int n);
  std::vector<std::array<float, 4>> probe_transmittance(std::array<float, 3> o, std::array<float, 3> d, int n);

  const std::string& device_name() const;
  uint32_t features() const;  // the kernels' st_feature mask
  const SceneDesc& scene() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace spectrack
