// renderer_impl.h: the parts of one device's Renderer (renderer.h) shared by its files:
// renderer.cpp (set-up and the stage loop), batch_plan.cpp (the batch plan, the memory check, the
// buffers and the stage arguments) and renderer_guiding.cpp (the guide's training passes).
// Internal to src/integrator.
#pragma once
#include "integrator/renderer.h"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <iostream>

#include "guiding/guide_cache.h"
#include "integrator/film_watch.h"
#include "integrator/loop_policy.h"
#include "integrator/state_layout.h"
#include "device/device_scene.h"
#include "integrator/memory_budget.h"
#include "integrator/stage_table.h"
#include "util/phase.h"

namespace spectrack {
namespace render_detail {

using Clock = std::chrono::steady_clock;
inline double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// How one render's paths are cut into batches of whole samples per pixel.
// Shadow-ray entries per path slot and bounce: one per light, one more for equi-angular sampling
// (kernels/queues.h shadow_lights).
inline uint64_t shadow_lights(const st_scene& st) {
  return uint64_t(st.n_lights) + (st.equiangular.n_local > 0 ? 1u : 0u);
}

struct BatchPlan {
  uint64_t Q = 0;            // path slots
  uint64_t shadow_ring = 1;  // shadow-ray entries per (path slot, light), types.h
  uint64_t NL = 0;           // shadow-ray entries per path slot (lights * shadow_ring)
  uint64_t npix = 0, nch = 0;  // window pixels, paths per (pixel, sample)
  uint64_t spp = 0, total_paths = 0;
  uint64_t samples_per_batch = 0, batch_paths = 0, n_batches = 0;
  uint64_t ring = 0;         // batches in flight (result buffers)
  uint64_t L = 1;            // float4 per path in the result buffer (st_scene.result_layers)
  uint64_t moments = 0;      // 1: the film sums the beauty's squared samples too (the variance layer)
  uint64_t film_layers() const { return L + moments; }
  uint64_t batch_samples(uint64_t b) const { return std::min<uint64_t>(samples_per_batch, spp - b * samples_per_batch); }
};

struct RenderBuffers {
  cl::Buffer paths, shadows, queues, counters, results, film;
  cl::Buffer loop;  // the stage loop's state (st_loop, kernels/wavefront.h)
};

// The stage loop's progress on the host: its last copy of the device's loop state (read every
// few iterations: stage_loop.cpp) and what the host decides.
struct LoopState {
  st_loop dev{};                      // the device's loop state, as last read
  st_loop reads[2] = {};              // the non-blocking reads' targets (stage_loop.cpp drive_loop)
  uint64_t accumulated = 0, samples_done = 0;  // of dev, for the watch and the film
  uint64_t samples_before = 0;       // samples of a resumed film (FilmWatch::resume) before sample_begin
  uint64_t batches_issuable = UINT64_MAX;  // batches that may be issued before the watch looks again
  bool time_limit_reached = false, noise_target_reached = false;
  bool lockstep = false;             // one iteration per read (training records, the watch, the trace, sized)
  bool sized = false;                // each launch sized by the state last read (stage_loop.cpp)
  uint64_t chunk = 1;                // iterations enqueued per read
  uint64_t host_waits = 0;           // blocking reads and finishes in the stage loop
};

}  // namespace render_detail

using namespace render_detail;

struct Renderer::Impl {
  SceneDesc scene;
  RenderOptions opt;
  RenderSettings settings;
  DeviceScene ds;
  std::unique_ptr<KernelLauncher> launcher;
  Clock::time_point t_created = Clock::now();
  double seconds_setup = 0, seconds_build = 0;
  bool from_cache = false;
  StateLayout state_layout = StateLayout::aos;  // the path state's layout on this device
  LoopPolicy loop_policy;                       // the stage loop's launches on this device (loop_policy.h)

  // volume path guiding: the cache (an empty header when off) and the training passes' records
  GuideCache guide;
  cl::Buffer b_guide, b_records;
  GuideInfo guide_info;
  bool guide_trained = false;
  bool guide_loaded = false;   // the cache came from --guide-cache's file: the training samples are rendered on demand
  RenderResult guide_samples;  // the training passes' film sums (the window's), added to the renders that hold them
  bool watch_with_training = false;  // the render's film holds guide_samples: the watch sees them on it

  // adaptive sampling: the entries the next stage loop renders (kernels/queues.h
  // active_pixels_offset), each a window pixel and the offset of its first sample from the
  // render's; empty without adaptive sampling
  std::vector<uint32_t> active_pixels, active_offsets;

  void setup();
  void warm_kernels();
  RenderResult render(int64_t sample_begin, int spp);
  RenderResult empty_film(int64_t sample_begin) const;
  // The stage loop over samples [sample_begin, sample_begin + spp); with `records`, a training
  // pass: the radiance records are collected into it and the film is the caller's to drop.
  RenderResult run_stage_loop(int64_t sample_begin, int spp, std::vector<st_guide_record>* records);
  void upload_guide();
  void drain_records(std::vector<st_guide_record>& out);
  // The training passes over the full film, settings.guide_training_samples samples kept; returns
  // their seconds.
  double train_guide();
  void report_guide(int pass) const;
  double load_guide();             // the cache from --guide-cache's file; returns its seconds
  void render_training_samples();  // with a loaded cache: the training pass's samples of the window
  void finish_guide();             // the render's settings in the trained or loaded cache's header
  struct TrainingState {           // renderer_guiding.cpp
    explicit TrainingState(Impl& r);
    ~TrainingState();
    void restore();
    Impl& r;
    const uint32_t seed;
    const FilmWindow window;
    const st_guide_header header;
    const std::function<void(double)> progress;
    bool restored = false;
  };
  nlohmann::json guide_cache_key() const;  // what the cache depends on (guide_cache_file.h)
  void add_guide_samples(RenderResult& res);
  int64_t guide_record_samples() const;  // RenderOptions::guide_record_samples, else the setting
  void set_window(const FilmWindow& w);

  // Paths per batch (rounded up to whole samples): 2Q with two batches in flight, so one batch
  // fills the slots while the other finishes; Q with the ring, so the first pass is done sooner.
  uint64_t batch_target_paths(uint64_t Q) const {
    return opt.batches_in_flight.value_or(ST_MAX_BATCHES_IN_FLIGHT) <= 2 ? 2 * Q : Q;
  }
  // Batches that may be issued beyond the accumulated ones: the first batch alone (its longest
  // paths finish sooner without later batches sharing the device, so the first pass, a preview,
  // is on the film early), then the whole ring.
  static uint64_t batches_ahead(uint64_t accumulated, uint64_t ring) { return accumulated == 0 ? 1 : ring; }
  BatchPlan plan_batches(int spp) const;
  MemoryNeed memory_need(const BatchPlan& plan) const;  // what a render with this plan takes (memory_budget.h)
  void check_memory(const BatchPlan& plan) const;
  void set_ring_size(uint64_t ring);
  RenderBuffers allocate(const BatchPlan& plan);
  void bind_stage_args(const RenderBuffers& b, const BatchPlan& plan);
  // The stage loop on the device (stage_loop.cpp): its first state, the enqueueing of iterations,
  // what the host does with each read of the state (false: the loop is over), and the statistics.
  void start_loop(const RenderBuffers& b, const BatchPlan& plan, LoopState& s, int64_t sample_begin);
  void enqueue_iterations(const BatchPlan& plan, const LoopState& s, uint64_t n);
  bool see_loop(const RenderBuffers& b, const BatchPlan& plan, LoopState& s, const st_loop& read, RenderResult& res,
                std::vector<st_guide_record>* records);
  void drive_loop(const RenderBuffers& b, const BatchPlan& plan, LoopState& s, RenderResult& res,
                  std::vector<st_guide_record>* records);
  void loop_stats(const BatchPlan& plan, const LoopState& s, RenderStats& S) const;
  bool stop_requested(LoopState& s) const;
  size_t launch_items(uint64_t capacity) const;  // work-items of a launch over a queue of this capacity
  RenderResult result_header(int64_t sample_begin, int spp) const;
  void read_film(const RenderBuffers& b, const BatchPlan& plan, const LoopState& s, RenderResult& res);
  void read_pixel_work(const RenderBuffers& b, const BatchPlan& plan, RenderResult& res);
  // The watch of the stage loop (film_watch.h; renderer_watch.cpp): the film state, the resumed
  // film, a look at the film after new batches (true: stop), the batches it lets the loop issue.
  FilmState film_state(const RenderBuffers& b, const BatchPlan& plan, const LoopState& s, int64_t sample_begin);
  void load_film_state(const RenderBuffers& b, const BatchPlan& plan, const FilmState& st);
  bool watch_film(const RenderBuffers& b, const BatchPlan& plan, LoopState& s, const RenderResult& header);
  void limit_issue(LoopState& s, const BatchPlan& plan, const FilmWatch& w);
  int64_t watched_training_samples() const;
  // The stage kernels launched for this scene, in launch order.
  std::vector<const Stage*> launched_stages() const;
};

}  // namespace spectrack
