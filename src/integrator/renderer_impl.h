// renderer_impl.h: the parts of one device's Renderer (renderer.h) shared by its files:
// renderer.cpp (set-up and the stage loop), batch_plan.cpp (the batch plan, the memory check, the
// buffers and the stage arguments) and renderer_guiding.cpp (the guide's training passes).
// Internal to src/integrator.
#pragma once
#include "integrator/renderer.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <iostream>

#include "guiding/guide_cache.h"
#include "integrator/film_watch.h"
#include "device/device_scene.h"
#include "integrator/memory_budget.h"
#include "util/phase.h"

namespace spectrack {
namespace render_detail {

using Clock = std::chrono::steady_clock;
inline double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// The stages of one iteration in launch order, each with the queue it reads.
struct Stage {
  const char* kernel;
  st_queue queue;
};
constexpr Stage kStages[] = {{"k_raygen", ST_Q_FREE},     {"k_track", ST_Q_TRACK},   {"k_escape", ST_Q_ESCAPE},
                             {"k_scatter", ST_Q_SCATTER}, {"k_shadow", ST_Q_SHADOW}, {"k_finish", ST_Q_FINISH}};
static_assert(sizeof(kStages) / sizeof(kStages[0]) == ST_Q_COUNT, "one stage per queue");

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
};

// The stage loop's progress.
struct LoopState {
  uint64_t n_q[ST_Q_COUNT] = {};  // FREE: size of the free stack (kernels/queues.h free_push)
  uint64_t free_kept = 0;           // free slots raygen left below its launch this iteration
  uint32_t cur = 0;
  uint64_t issued = 0, accumulated = 0, samples_done = 0, batches_target = 0;
  uint64_t samples_before = 0;       // samples of a resumed film (FilmWatch::resume) before sample_begin
  uint64_t batches_issuable = UINT64_MAX;  // batches that may be issued before the watch looks again
  bool time_limit_reached = false, noise_target_reached = false;
  std::vector<uint64_t> batch_done;  // finished paths per ring slot
  std::vector<uint32_t> counters = std::vector<uint32_t>(ST_C_COUNT, 0u);
  uint32_t max_bits = 0;             // of the largest throughput component
};

inline void record_occupancy(RenderStats& S, const uint64_t* n_q, uint64_t Q) {
  uint64_t busy = 0;
  for (int q = ST_Q_TRACK; q < ST_Q_PATH_QUEUES; ++q) busy += n_q[q];  // path slots (shadow rays are per light)
  double occ = double(busy) / double(Q);
  // running mean over the iterations recorded so far (S.iterations counts this one)
  S.occupancy_mean += (occ - S.occupancy_mean) / double(S.iterations);
  S.occupancy_min = S.iterations == 1 ? occ : std::min(S.occupancy_min, occ);
  if (occ < 0.5) S.iterations_below_half++;
}

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

  // volume path guiding: the cache (an empty header when off) and the training passes' records
  GuideCache guide;
  cl::Buffer b_guide, b_records;
  GuideInfo guide_info;
  bool guide_trained = false;
  RenderResult guide_samples;  // the training passes' film sums, added to the first render's image

  // adaptive sampling: the window pixels the next stage loop renders (kernels/queues.h
  // active_pixels_offset); empty without adaptive sampling
  std::vector<uint32_t> active_pixels;

  void setup();
  void warm_kernels();
  RenderResult render(int64_t sample_begin, int spp);
  // The stage loop over samples [sample_begin, sample_begin + spp); with `records`, a training
  // pass: the radiance records are collected into it and the film is the caller's to drop.
  RenderResult run_stage_loop(int64_t sample_begin, int spp, std::vector<st_guide_record>* records);
  void upload_guide();
  void drain_records(std::vector<st_guide_record>& out);
  // The training passes, leaving at least one of `spp` samples to the render; returns its seconds.
  double train_guide(int spp);
  void add_guide_samples(RenderResult& res);

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
  bool begin_iteration(LoopState& s, const BatchPlan& plan, int64_t sample_begin);
  void fold_counters(LoopState& s, const BatchPlan& plan, RenderStats& S) const;
  void accumulate_finished(LoopState& s, const BatchPlan& plan, RenderResult& res);
  RenderResult result_header(int64_t sample_begin, int spp) const;
  void read_film(const RenderBuffers& b, const BatchPlan& plan, const LoopState& s, RenderResult& res);
  // The watch of the stage loop (film_watch.h; renderer_watch.cpp): the film state, the resumed
  // film, a look at the film after new batches (true: stop), the batches it lets the loop issue.
  FilmState film_state(const RenderBuffers& b, const BatchPlan& plan, const LoopState& s, int64_t sample_begin);
  void load_film_state(const RenderBuffers& b, const BatchPlan& plan, const FilmState& st);
  bool watch_film(const RenderBuffers& b, const BatchPlan& plan, LoopState& s, const RenderResult& header);
  void limit_issue(LoopState& s, const BatchPlan& plan, const FilmWatch& w);
  // Construction to the first batch on the film (waits for the accumulation launch).
  double first_pass_seconds() {
    ST_CL_CHECK(ds.queue.finish(), "finish first pass");
    return seconds_since(t_created);
  }
};

}  // namespace spectrack
