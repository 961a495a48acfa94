// renderer.cpp: the wavefront stage loop on one device (see renderer.h for the design).
// Set-up: resolve the settings (render/settings.h), pack the scene (render/scene_pack.h), choose
// the device and upload (render/device_scene.h), build the kernels (cached) for the scene's
// st_feature mask (--generic-kernels: every feature and ST_MAX_MEDIA media). A render is then a
// few named steps: plan the batches, check the memory, allocate, bind the stage arguments, run the
// iterations (launch the stages, read the counters, fold them into the statistics, add finished
// batches to the film), read the film back. What a scene lacks costs nothing: a scene without
// lights gets no shadow-ray buffer or queue, and one whose escaping rays see no light gets no
// escape launch (track sends them straight to finish). With guiding, the first render trains the
// guide cache (docs/guiding.md): a few passes over the full film with random streams of their own,
// whose images are dropped and whose radiance records are drained after every iteration and fitted
// on the host; the render then runs with the cache, its training time counted in seconds_render.
#include "render/renderer.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <iostream>

#include "guiding/guide_cache.h"
#include "render/device_scene.h"
#include "render/memory_budget.h"
#include "util/phase.h"

namespace spectrack {
namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// The stages of one iteration in launch order, each with the queue it reads.
struct Stage {
  const char* kernel;
  st_queue queue;
};
constexpr Stage kStages[] = {{"k_raygen", ST_Q_FREE},     {"k_track", ST_Q_TRACK},   {"k_escape", ST_Q_ESCAPE},
                             {"k_scatter", ST_Q_SCATTER}, {"k_shadow", ST_Q_SHADOW}, {"k_finish", ST_Q_FINISH}};
static_assert(sizeof(kStages) / sizeof(kStages[0]) == ST_Q_COUNT, "one stage per queue");

// How one render's paths are cut into batches of whole samples per pixel.
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
  bool time_limit_reached = false;
  std::vector<uint64_t> batch_done;  // finished paths per ring slot
  std::vector<uint32_t> counters = std::vector<uint32_t>(ST_C_COUNT, 0u);
  uint32_t max_bits = 0;             // of the largest throughput component
};

void record_occupancy(RenderStats& S, const uint64_t* n_q, uint64_t Q) {
  uint64_t busy = 0;
  for (int q = ST_Q_TRACK; q < ST_Q_PATH_QUEUES; ++q) busy += n_q[q];  // path slots (shadow rays are per light)
  double occ = double(busy) / double(Q);
  // running mean over the iterations recorded so far (S.iterations counts this one)
  S.occupancy_mean += (occ - S.occupancy_mean) / double(S.iterations);
  S.occupancy_min = S.iterations == 1 ? occ : std::min(S.occupancy_min, occ);
  if (occ < 0.5) S.iterations_below_half++;
}

// What sizes the buffers of path slots and shadow rays, for messages: the options given
// (--path-slots, --shadow-ring) are named, so that a refusal says which one to lower.
std::string slot_cause(const RenderOptions& opt, const BatchPlan& p, bool shadows) {
  std::string s = opt.path_slots > 0 ? fmt::format("--path-slots {}", p.Q) : fmt::format("{} path slots", p.Q);
  if (shadows)
    s += fmt::format(" x {} light(s) x {}", p.NL / std::max<uint64_t>(1, p.shadow_ring),
                     opt.shadow_ring > 0 ? fmt::format("--shadow-ring {}", p.shadow_ring)
                                         : fmt::format("shadow ring {}", p.shadow_ring));
  return s;
}

}  // namespace

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

  void setup();
  void warm_kernels();
  RenderResult render(int64_t sample_begin, int spp);
  // The stage loop over samples [sample_begin, sample_begin + spp); with `records`, a training
  // pass: the radiance records are collected into it and the film is the caller's to drop.
  RenderResult run_stage_loop(int64_t sample_begin, int spp, std::vector<st_guide_record>* records);
  void upload_guide();
  void drain_records(std::vector<st_guide_record>& out);
  double train_guide();  // returns its seconds

  // Paths per batch (rounded up to whole samples): 2Q with two batches in flight, so one batch
  // fills the slots while the other finishes; Q with the ring, so the first pass is done sooner.
  uint64_t batch_target_paths(uint64_t Q) const {
    return (opt.batches_in_flight > 0 && opt.batches_in_flight <= 2) ? 2 * Q : Q;
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
  // Construction to the first batch on the film (waits for the accumulation launch).
  double first_pass_seconds() {
    ST_CL_CHECK(ds.queue.finish(), "finish first pass");
    return seconds_since(t_created);
  }
};

void Renderer::Impl::setup() {
  auto t0 = Clock::now();
  settings = resolve_settings(scene, opt);
  set_phase("scene packing (volumes, environment maps and their CDFs, majorant grids)");
  PackedScene packed = pack_scene(scene, settings, {opt.majorant_cell, opt.majorant_block, opt.iteration_budget, opt.majorant_step_cost});
  // the feature mask is in the source, hence in the kernel-cache key
  if (opt.generic_kernels) packed.features = ST_FEATURES_ALL;
  packed.features |= opt.feature_floor & uint32_t(ST_FEATURES_ALL);
  if (settings.guiding) packed.features |= ST_FEATURE_GUIDING;
  const int max_media = opt.generic_kernels ? ST_MAX_MEDIA : std::max(1, packed.st.n_media);
  std::vector<std::pair<std::string, std::string>> defines = {
      {"ST_KERNEL_MAX_MEDIA", std::to_string(max_media)}, {"ST_FEATURES", fmt::format("0x{:x}u", packed.features)}};
  set_phase("device upload and kernel build");
  ds = upload_scene(opt.device, std::move(packed), std::move(defines));
  // guiding off: a header of zeros (nothing guides, nothing records); the kernels compiled without
  // ST_FEATURE_GUIDING never read it
  if (settings.guiding) guide = make_guide_cache(ds.packed.st, opt.guide_grid_cells > 0 ? opt.guide_grid_cells : kGuideGridCells);
  const std::vector<unsigned char> g = guide.serialize();
  b_guide = ds.buffer(CL_MEM_READ_ONLY, g.size(), g.data(), "guide cache");
  const uint32_t no_records[4] = {0, 0, 0, 0};
  b_records = ds.buffer(CL_MEM_READ_WRITE, sizeof(no_records), no_records, "guide records");
  auto tb = Clock::now();
  ProgramBuild pb = build_program(ds.ctx, ds.dev, assemble_kernel_source(ds.defines), "-cl-std=CL1.2", opt.quiet);
  launcher = std::make_unique<KernelLauncher>(ds.queue, pb.program);
  from_cache = pb.from_cache;
  warm_kernels();
  seconds_build = seconds_since(tb);
  seconds_setup = seconds_since(t0);
}

// PoCL compiles each kernel for its work-group size at its first launch (seconds per kernel with
// a cold PoCL cache), which would land in the first render's stage loop: one empty launch of each
// kernel the renders can launch, at the real work-group size, moves it here, into seconds_build.
// Every item returns at once without touching memory: the stage kernels see queue sizes and
// n_new of 0, k_accumulate npix = 0 (each kernel's first statement). The escape stage is skipped
// when the kernels have none (track never queues an escape), the shadow stage without lights.
void Renderer::Impl::warm_kernels() {
  const cl::Buffer none = ds.buffer(CL_MEM_READ_WRITE, 16, nullptr, "warm-up");
  const st_iteration idle{};
  for (const Stage& s : kStages) {
    if (s.queue == ST_Q_ESCAPE && !(ds.packed.features & ST_FEATURE_ESCAPE)) continue;
    if (s.queue == ST_Q_SHADOW && ds.packed.st.n_lights == 0) continue;
    cl::Kernel& k = launcher->kernel(s.kernel);
    k.setArg(ST_ARG_SCENE, ds.b_scene);
    k.setArg(ST_ARG_GRIDS, ds.b_grids);
    k.setArg(ST_ARG_MAJORANTS, ds.b_maj);
    k.setArg(ST_ARG_ENV, ds.b_env);
    for (int a : {ST_ARG_PATHS, ST_ARG_SHADOWS, ST_ARG_QUEUES, ST_ARG_COUNTERS, ST_ARG_RESULTS, ST_ARG_GUIDE,
                  ST_ARG_GUIDE_RECORDS})
      k.setArg(a, none);
    k.setArg(ST_ARG_SLOTS, cl_uint(0));
    k.setArg(ST_ARG_LIGHTS, cl_uint(0));
    k.setArg(ST_ARG_ITERATION, idle);
    launcher->warm(s.kernel);
  }
  cl::Kernel& acc = launcher->kernel("k_accumulate");
  acc.setArg(0, none);
  acc.setArg(1, none);
  for (int a = 2; a < 8; ++a) acc.setArg(a, cl_uint(0));
  launcher->warm("k_accumulate");
  ST_CL_CHECK(ds.queue.finish(), "kernel warm-up");
}

BatchPlan Renderer::Impl::plan_batches(int spp) const {
  BatchPlan p;
  // the shadow ring (types.h): 2 by default, which removes most waiting where shadow rays take
  // several launches and costs nothing measurable where they do not (bench/RESULTS.md, "No
  // waiting paths")
  p.shadow_ring = opt.shadow_ring > 0 ? uint64_t(opt.shadow_ring) : uint64_t(kDefaultShadowRing);
  if (p.shadow_ring > ST_MAX_SHADOW_RING)
    throw Error(fmt::format("shadow ring {} is above the maximum of {}", p.shadow_ring, ST_MAX_SHADOW_RING));
  p.NL = uint64_t(ds.packed.st.n_lights) * p.shadow_ring;
  p.npix = settings.window.pixels();
  p.nch = uint64_t(settings.channels_per_sample);
  p.spp = uint64_t(spp);
  p.Q = opt.path_slots > 0 ? uint64_t(opt.path_slots) : ((ds.dev.type & CL_DEVICE_TYPE_GPU) ? (1u << 20) : (1u << 16));
  p.total_paths = p.spp * p.npix * p.nch;
  p.Q = std::max<uint64_t>(1, std::min<uint64_t>(p.Q, p.total_paths));
  p.samples_per_batch = std::max<uint64_t>(1, (batch_target_paths(p.Q) + p.npix * p.nch - 1) / (p.npix * p.nch));
  p.samples_per_batch = std::min<uint64_t>(p.samples_per_batch, p.spp);
  p.batch_paths = p.samples_per_batch * p.npix * p.nch;
  p.L = uint64_t(ds.packed.st.result_layers);
  p.moments = (settings.aovs & ST_AOV_BIT(VARIANCE)) ? 1 : 0;
  // the kernels index the result buffer (L float4 per path) with 32-bit integers
  if (p.batch_paths * p.L >= (uint64_t(1) << 32))
    throw Error(fmt::format("film too large: one sample of every pixel is {} paths of {} result layers, more than "
                            "2^32 values (fewer film layers, or a tile with --pixel-bounds)",
                            p.batch_paths, p.L));
  p.n_batches = (p.spp + p.samples_per_batch - 1) / p.samples_per_batch;
  // A ring of result buffers: more than two batches in flight keep the slots busy while a batch's
  // longest paths finish; capped by ST_MAX_BATCHES_IN_FLIGHT, the batch count, 32-bit indices and
  // the device's largest buffer (film layers make each path's result L float4).
  uint64_t k = opt.batches_in_flight > 0 ? uint64_t(opt.batches_in_flight) : uint64_t(ST_MAX_BATCHES_IN_FLIGHT);
  k = std::min<uint64_t>({k, uint64_t(ST_MAX_BATCHES_IN_FLIGHT), std::max<uint64_t>(1, p.n_batches)});
  while (k > 1 && (k * p.batch_paths * p.L >= (uint64_t(1) << 32) ||
                   k * p.batch_paths * p.L * sizeof(st_float4) > uint64_t(ds.dev.max_alloc)))
    --k;
  p.ring = k;
  return p;
}

MemoryNeed Renderer::Impl::memory_need(const BatchPlan& p) const {
  RenderShape r;
  r.npix = p.npix;
  r.film_layers = p.film_layers();
  r.aov_channels = aov_sum_channels(settings.aovs).size();
  r.path_slots = p.Q;
  r.path_bytes = sizeof(st_path) + p.NL * sizeof(st_shadow) + (settings.guiding ? guide_record_buffer_bytes(1, true) : 0);
  r.queue_words = 2 * (ST_Q_PATH_QUEUES + p.NL);
  r.result_values = p.ring * p.batch_paths * p.L;
  r.scene_bytes = ds.scene_bytes + (settings.guiding ? double(guide.bytes()) : 0.0);
  return render_memory(r);
}

void Renderer::Impl::check_memory(const BatchPlan& p) const {
  const MemoryNeed need = memory_need(p);
  const std::string what = fmt::format("this render ({}x{} film of {} layers: {:.1f} MiB; {} path slots: {:.1f} MiB, "
                                       "from {}; batch results: {:.1f} MiB)",
                                       settings.window.width, settings.window.height, p.film_layers(),
                                       need.film_device / 1048576.0, p.Q, need.slots_device / 1048576.0,
                                       slot_cause(opt, p, true), need.results_device / 1048576.0);
  const std::string slots_advice =
      opt.path_slots > 0 || opt.shadow_ring > 0
          ? fmt::format("{}{}{}", opt.path_slots > 0 ? "a lower --path-slots" : "",
                        opt.path_slots > 0 && opt.shadow_ring > 0 ? " or " : "",
                        opt.shadow_ring > 0 ? "a lower --shadow-ring" : "")
          : std::string("fewer --path-slots");
  const std::string advice = "use " + slots_advice +
                             ", a smaller film (or a tile with --pixel-bounds), fewer film layers, or another device "
                             "with --device";
  if (need.device > double(ds.dev.global_mem))
    throw Error(fmt::format("{} needs about {:.1f} MiB of device memory but device '{}' has {:.1f} MiB; {}", what,
                            need.device / 1048576.0, ds.dev.name, ds.dev.global_mem / 1048576.0, advice));
  // a CPU device's global memory is the host's
  const bool shared = (ds.dev.type & CL_DEVICE_TYPE_CPU) != 0;
  check_host_memory(need.host + (shared ? need.device - need.scene_device : 0.0), what, advice);
}

// Batch b uses ring slot b % ring: the kernels read the ring size from the scene constants.
void Renderer::Impl::set_ring_size(uint64_t ring) {
  if (ds.packed.st.batches_in_flight == int(ring)) return;
  ds.packed.st.batches_in_flight = int(ring);
  ds.write_scene_constants();
}

RenderBuffers Renderer::Impl::allocate(const BatchPlan& p) {
  RenderBuffers b;
  b.paths = ds.buffer(CL_MEM_READ_WRITE, p.Q * sizeof(st_path), nullptr,
                      fmt::format("path states ({})", slot_cause(opt, p, false)).c_str());
  b.shadows = ds.buffer(CL_MEM_READ_WRITE, p.Q * p.NL * sizeof(st_shadow), nullptr,
                        fmt::format("shadow rays ({})", slot_cause(opt, p, true)).c_str());
  // every entry starts empty (st_shadow.state 0); a path leaves its entries empty when it finishes
  if (p.Q * p.NL > 0)
    ST_CL_CHECK(ds.queue.enqueueFillBuffer(b.shadows, cl_uint(ST_SHADOW_EMPTY), 0, p.Q * p.NL * sizeof(st_shadow)),
                "clear the shadow-ray entries");
  ST_CL_CHECK(ds.queue.finish(), "allocate render buffers");  // set-up, not seconds_render
  // two parities of: the path-slot queues (Q each), then the shadow queue (Q * NL)
  const uint64_t per_parity = ST_Q_PATH_QUEUES * p.Q + p.Q * p.NL;
  std::vector<uint32_t> init_queue(2 * per_parity, 0u);
  for (uint64_t i = 0; i < p.Q; ++i) init_queue[i] = uint32_t(i);  // parity 0, FREE: every slot
  b.queues = ds.buffer(CL_MEM_READ_WRITE, init_queue.size() * 4, init_queue.data(),
                       fmt::format("queues ({})", slot_cause(opt, p, true)).c_str());
  std::vector<uint32_t> counters(ST_C_COUNT, 0u);
  b.counters = ds.buffer(CL_MEM_READ_WRITE, counters.size() * 4, counters.data(), "counters");
  b.results = ds.buffer(CL_MEM_READ_WRITE, p.ring * p.batch_paths * p.L * sizeof(st_float4), nullptr, "batch results");
  // film: per layer, per pixel the running sum, then its Kahan compensation terms (finish.cl),
  // cleared on the device (no host copy of zeros)
  const size_t film_bytes = 2 * p.npix * p.film_layers() * sizeof(st_float4);
  b.film = ds.buffer(CL_MEM_READ_WRITE, film_bytes, nullptr, "film");
  ST_CL_CHECK(ds.queue.enqueueFillBuffer(b.film, cl_uint(0), 0, film_bytes), "clear the film");
  ST_CL_CHECK(ds.queue.finish(), "clear the film");
  return b;
}

void Renderer::Impl::bind_stage_args(const RenderBuffers& b, const BatchPlan& p) {
  for (const Stage& s : kStages) {
    cl::Kernel& k = launcher->kernel(s.kernel);
    k.setArg(ST_ARG_SCENE, ds.b_scene);
    k.setArg(ST_ARG_GRIDS, ds.b_grids);
    k.setArg(ST_ARG_MAJORANTS, ds.b_maj);
    k.setArg(ST_ARG_ENV, ds.b_env);
    k.setArg(ST_ARG_PATHS, b.paths);
    k.setArg(ST_ARG_SHADOWS, b.shadows);
    k.setArg(ST_ARG_QUEUES, b.queues);
    k.setArg(ST_ARG_COUNTERS, b.counters);
    k.setArg(ST_ARG_RESULTS, b.results);
    k.setArg(ST_ARG_SLOTS, cl_uint(p.Q));
    k.setArg(ST_ARG_LIGHTS, cl_uint(p.NL));
    k.setArg(ST_ARG_GUIDE, b_guide);
    k.setArg(ST_ARG_GUIDE_RECORDS, b_records);
  }
  cl::Kernel& acc = launcher->kernel("k_accumulate");
  acc.setArg(0, b.results);
  acc.setArg(1, b.film);
}

// Launches one iteration's stages; false on a stop request or at the deadline, which end the
// render at once: the film holds the batches finished so far (samples 0 .. samples_done - 1 of
// the range, every batch being whole samples of every pixel), and the paths in flight are dropped.
bool Renderer::Impl::begin_iteration(LoopState& s, const BatchPlan& p, int64_t sample_begin) {
  if (opt.stop && opt.stop->load()) return false;
  if (opt.deadline && Clock::now() >= *opt.deadline) {
    s.time_limit_reached = true;
    return false;
  }
  uint64_t issue_limit = std::min<uint64_t>(p.total_paths, (s.accumulated + batches_ahead(s.accumulated, p.ring)) * p.batch_paths);
  issue_limit = std::min<uint64_t>(issue_limit, s.batches_target * p.batch_paths);
  uint64_t n_new = std::min<uint64_t>(s.n_q[ST_Q_FREE], issue_limit > s.issued ? issue_limit - s.issued : 0);
  uint64_t in_flight = 0;
  for (int q = ST_Q_TRACK; q < ST_Q_COUNT; ++q) in_flight += s.n_q[q];
  if (n_new == 0 && in_flight == 0)
    throw Error(fmt::format("internal: wavefront stalled with {} of {} batches accumulated", s.accumulated, s.batches_target));
  st_iteration it{};
  it.first = s.issued;
  it.cur = s.cur;
  for (int q = 0; q < ST_Q_COUNT; ++q) it.n_queue[q] = cl_uint(s.n_q[q]);
  it.n_new = cl_uint(n_new);
  it.batch_paths = cl_uint(p.batch_paths);
  it.sample_begin = cl_uint(sample_begin);
  it.samples_per_batch = cl_uint(p.samples_per_batch);
  for (const Stage& st : kStages) launcher->kernel(st.kernel).setArg(ST_ARG_ITERATION, it);
  // raygen runs over the n_new slots it fills (the top of the free stack); the others stay put
  for (const Stage& st : kStages) launcher->launch(st.kernel, st.queue == ST_Q_FREE ? n_new : s.n_q[st.queue]);
  s.free_kept = s.n_q[ST_Q_FREE] - n_new;
  s.issued += n_new;
  return true;
}

void Renderer::Impl::fold_counters(LoopState& s, const BatchPlan& p, RenderStats& S) const {
  const std::vector<uint32_t>& c = s.counters;
  for (int q = 0; q < ST_Q_COUNT; ++q) s.n_q[q] = c[ST_C_QUEUE + q];
  s.n_q[ST_Q_FREE] = s.free_kept + c[ST_C_QUEUE + ST_Q_FREE];  // the stack: kept + pushed by finish
  // every path slot is in exactly one path queue at an iteration boundary
  uint64_t slots = 0;
  for (int q = 0; q < ST_Q_PATH_QUEUES; ++q) slots += s.n_q[q];
  if (slots != p.Q)
    throw Error(fmt::format("internal: the path queues hold {} slots after iteration {}, not {}", slots, S.iterations, p.Q));
  record_occupancy(S, s.n_q, p.Q);
  s.cur = 1 - s.cur;
  static const bool trace = [] {
    const char* e = std::getenv("SPECTRACK_TRACE_QUEUES");
    return e && std::string(e) != "0";
  }();
  if (trace)
    std::cerr << fmt::format("iteration {}: issued {} free {} track {} escape {} scatter {} finish {} shadow {} "
                             "done {}+{} accumulated {}\n",
                             S.iterations, s.issued, s.n_q[ST_Q_FREE], s.n_q[ST_Q_TRACK], s.n_q[ST_Q_ESCAPE],
                             s.n_q[ST_Q_SCATTER], s.n_q[ST_Q_FINISH], s.n_q[ST_Q_SHADOW],
                             s.batch_done[0] + c[ST_C_BATCH_DONE], p.ring > 1 ? s.batch_done[1] + c[ST_C_BATCH_DONE + 1] : 0,
                             s.accumulated);
  for (uint64_t r = 0; r < p.ring; ++r) s.batch_done[r] += c[ST_C_BATCH_DONE + r];
#define ST_X_FOLD(E, field, key) S.field += c[ST_C_##E];
  ST_SUM_COUNTERS(ST_X_FOLD)
#undef ST_X_FOLD
  s.max_bits = std::max(s.max_bits, c[ST_C_MAX_THROUGHPUT_BITS]);
}

// Adds every completed batch to the film, in batch order.
void Renderer::Impl::accumulate_finished(LoopState& s, const BatchPlan& p, RenderResult& res) {
  cl::Kernel& acc = launcher->kernel("k_accumulate");
  while (s.accumulated < s.batches_target) {
    uint64_t b = s.accumulated;
    uint64_t expected = p.batch_samples(b) * p.npix * p.nch;
    if (s.batch_done[b % p.ring] < expected) break;
    acc.setArg(2, cl_uint((b % p.ring) * p.batch_paths));
    acc.setArg(3, cl_uint(p.batch_samples(b)));
    acc.setArg(4, cl_uint(p.npix));
    acc.setArg(5, cl_uint(p.nch));
    acc.setArg(6, cl_uint(p.L));
    acc.setArg(7, cl_uint(p.moments));
    launcher->launch("k_accumulate", p.npix);
    s.batch_done[b % p.ring] -= expected;
    s.samples_done += p.batch_samples(b);
    res.stats.paths += expected;
    if (s.accumulated == 0) res.seconds_first_pass = first_pass_seconds();
    ++s.accumulated;
  }
}

RenderResult Renderer::Impl::result_header(int64_t sample_begin, int spp) const {
  RenderResult res;
  res.width = settings.window.width;
  res.height = settings.window.height;
  res.full_width = settings.full_width;
  res.full_height = settings.full_height;
  res.x0 = settings.window.x0;
  res.y0 = settings.window.y0;
  res.sample_begin = sample_begin;
  res.spp_requested = spp;
  res.record_settings(settings);
  res.device = ds.dev.name;
  res.seconds_setup = seconds_setup;
  res.seconds_build = seconds_build;
  res.kernels_from_cache = from_cache;
  res.features = ds.packed.features;
  res.light_sampling_used = ds.packed.st.light_sampling;
  res.majorants = ds.packed.majorants;
  return res;
}

void Renderer::Impl::read_film(const RenderBuffers& b, const BatchPlan& p, const LoopState& s, RenderResult& res) {
  res.spp_done = int(s.samples_done);
  res.interrupted = s.samples_done < p.spp;
  res.time_limit_reached = s.time_limit_reached;
  res.aov_channels = aov_sum_channels(settings.aovs);
  const size_t na = res.aov_channels.size();
  res.rgb.assign(p.npix * 3, 0.0f);
  res.sum.assign(p.npix * 3, 0.0);
  res.aov_sum.assign(p.npix * na, 0.0);
  // the film comes back in chunks of pixels (every layer's sums and compensations of the chunk),
  // so the host never holds a copy of the whole device film
  const uint64_t segments = 2 * p.film_layers(), chunk = std::min<uint64_t>(p.npix, uint64_t(1) << 16);
  std::vector<st_float4> film(segments * chunk);
  uint64_t i0 = 0;
  // Kahan: the exact sum of layer l is (to float rounding of the terms) sum - compensation
  auto layer = [&](uint64_t l, uint64_t i, int k) {
    const st_float4& f = film[2 * l * chunk + (i - i0)];
    const st_float4& c = film[(2 * l + 1) * chunk + (i - i0)];
    const float* fv = &f.x;
    const float* cv = &c.x;
    return double(fv[k]) - double(cv[k]);
  };
  for (uint64_t i = 0; i < p.npix; ++i) {
    if (i == i0 + chunk || i == 0) {
      i0 = i;
      const uint64_t n = std::min(chunk, p.npix - i0);
      for (uint64_t g = 0; g < segments; ++g)
        ST_CL_CHECK(ds.queue.enqueueReadBuffer(b.film, CL_FALSE, (g * p.npix + i0) * sizeof(st_float4),
                                               n * sizeof(st_float4), film.data() + g * chunk),
                    "read film");
      ST_CL_CHECK(ds.queue.finish(), "read film");
    }
    size_t a = 0;  // next aov channel, in aov_sum_channels order: alpha, environment, variance
    for (int k = 0; k < 3; ++k) {
      // the environment layer is the part of the beauty the paths did not keep (shade.cl): a
      // transparent film (alpha) leaves it out of R, G, B, an opaque one adds it back
      const double env = p.L > 1 && !(settings.aovs & ST_AOV_BIT(ALPHA)) ? layer(ST_RESULT_ENVIRONMENT, i, k) : 0.0;
      res.sum[i * 3 + k] = layer(ST_RESULT_BEAUTY, i, k) + env;
      if (s.samples_done > 0) res.rgb[i * 3 + k] = float(res.sum[i * 3 + k] / double(s.samples_done));
    }
    if (settings.aovs & ST_AOV_BIT(ALPHA))
      for (int k = 0; k < 3; ++k) res.aov_sum[i * na + a++] = layer(ST_RESULT_ALPHA, i, k);
    if (settings.aovs & ST_AOV_BIT(ENVIRONMENT))
      for (int k = 0; k < 3; ++k) res.aov_sum[i * na + a++] = layer(ST_RESULT_ENVIRONMENT, i, k);
    if (settings.aovs & ST_AOV_BIT(VARIANCE))
      for (int k = 0; k < 3; ++k) res.aov_sum[i * na + a++] = layer(p.L, i, k);
    if (settings.aovs & ST_AOV_BIT(EMISSION))
      for (int k = 0; k < 3; ++k) res.aov_sum[i * na + a++] = layer(ST_RESULT_EMISSION, i, k);
    if (settings.aovs & ST_AOV_BIT(DIRECT))
      for (int k = 0; k < 3; ++k) res.aov_sum[i * na + a++] = layer(ST_RESULT_DIRECT, i, k);
    if (settings.aovs & ST_AOV_BIT(INDIRECT))  // the rest of what the paths kept: the passes add up
      for (int k = 0; k < 3; ++k)
        res.aov_sum[i * na + a++] =
            layer(ST_RESULT_BEAUTY, i, k) - layer(ST_RESULT_EMISSION, i, k) - layer(ST_RESULT_DIRECT, i, k);
    if (settings.aovs & ST_AOV_BIT(ALBEDO))  // sums over the samples whose camera ray collided
      for (int k = 0; k < 3; ++k) res.aov_sum[i * na + a++] = layer(ST_RESULT_AUX, i, k);
    if (settings.aovs & ST_AOV_BIT(DEPTH)) res.aov_sum[i * na + a++] = layer(ST_RESULT_AUX, i, 3);
    if (settings.aovs & (ST_AOV_BIT(ALBEDO) | ST_AOV_BIT(DEPTH)))
      res.aov_sum[i * na + a++] = layer(ST_RESULT_ALPHA, i, 3);  // how many of them collided
  }
}

RenderResult Renderer::Impl::render(int64_t sample_begin, int spp) {
  if (sample_begin < 0 || spp < 1 || uint64_t(sample_begin) + uint64_t(spp) > (uint64_t(1) << 32))
    throw Error(fmt::format("sample range {}:{} is not a non-empty range of sample indices 0 .. 2^32",
                            sample_begin, sample_begin + spp));
  const double seconds_training = settings.guiding && !guide_trained ? train_guide() : 0.0;
  RenderResult res = run_stage_loop(sample_begin, spp, nullptr);
  res.seconds_render += seconds_training;  // efficiency counts the training
  res.guide = guide_info;
  return res;
}

void Renderer::Impl::upload_guide() {
  const std::vector<unsigned char> g = guide.serialize();
  ST_CL_CHECK(ds.queue.enqueueWriteBuffer(b_guide, CL_TRUE, 0, g.size(), g.data()), "upload the guide cache");
}

// Appends the records of the last iteration (their order is the device's; the fit sorts them)
// and empties the buffer. Its capacity (guide_record_capacity) is the most one iteration records.
void Renderer::Impl::drain_records(std::vector<st_guide_record>& out) {
  uint32_t n = 0;
  ST_CL_CHECK(ds.queue.enqueueReadBuffer(b_records, CL_TRUE, 0, 4, &n), "read the guide record count");
  if (n == 0) return;
  if (n > uint32_t(guide.header.dims[3]))
    throw Error(fmt::format("internal: {} guide records in one iteration, above the capacity {}", n, guide.header.dims[3]));
  const size_t first = out.size();
  out.resize(first + n);
  ST_CL_CHECK(ds.queue.enqueueReadBuffer(b_records, CL_TRUE, 16, size_t(n) * sizeof(st_guide_record), &out[first]),
              "read the guide records");
  const uint32_t zero = 0;
  ST_CL_CHECK(ds.queue.enqueueWriteBuffer(b_records, CL_TRUE, 0, 4, &zero), "reset the guide record count");
}

// The training passes: 1, 2, 4, ... samples per pixel (samples 0, 1-2, 3-6, ... of a seed of their
// own), each guided by the cache the previous one fitted; records are fitted once per pass.
double Renderer::Impl::train_guide() {
  auto t0 = Clock::now();
  const uint32_t seed = ds.packed.st.seed;
  ds.packed.st.seed = seed ^ kGuideTrainingSeed;
  ds.write_scene_constants();
  const auto progress = opt.progress;
  opt.progress = nullptr;
  std::vector<st_guide_record> records;
  int64_t begin = 0;
  guide_info = GuideInfo{};
  for (int k = 0; k < kGuideTrainingPasses; ++k) {
    records.clear();
    const RenderResult pass = run_stage_loop(begin, 1 << k, &records);
    begin += 1 << k;
    guide_info.regions_guided = fit_guide_cache(guide, records);
    if (opt.guide_cache_hook) opt.guide_cache_hook(guide);
    guide.header.origin.w = 1.0f;  // the next passes and the render sample the guide
    guide_info.records = records.size();
    guide_info.training_passes = k + 1;
    if (pass.interrupted) break;
  }
  guide.header.inv_cell.w = 0.0f;  // no records in the render
  upload_guide();
  opt.progress = progress;
  ds.packed.st.seed = seed;
  ds.write_scene_constants();
  guide_trained = true;
  guide_info.used = true;
  guide_info.bytes = guide.bytes();
  guide_info.regions = int(guide.regions.size());
  guide_info.seconds_training = seconds_since(t0);
  return guide_info.seconds_training;
}

RenderResult Renderer::Impl::run_stage_loop(int64_t sample_begin, int spp, std::vector<st_guide_record>* records) {
  RenderResult res = result_header(sample_begin, spp);
  launcher->times().clear();
  BatchPlan plan = plan_batches(spp);
  // the default shadow ring falls back to one entry per (path, light) where two would not fit (the
  // image is the same; paths may wait for their shadow rays)
  if (opt.shadow_ring == 0 && plan.shadow_ring > 1 && memory_need(plan).device > double(ds.dev.global_mem)) {
    plan.shadow_ring = 1;
    plan.NL = uint64_t(ds.packed.st.n_lights);
  }
  check_memory(plan);  // refuse what cannot fit before allocating anything
  set_phase("film allocation");
  set_ring_size(plan.ring);
  RenderBuffers buf = allocate(plan);
  if (settings.guiding) {  // the slots' guide state; training: records on, vertex rings, one iteration's records
    const uint64_t capacity = records ? guide_record_capacity(plan.Q) : 0;
    const uint32_t head[4] = {0, 0, 0, 0};
    b_records = ds.buffer(CL_MEM_READ_WRITE, guide_record_buffer_bytes(plan.Q, records != nullptr), nullptr, "guide records");
    ST_CL_CHECK(ds.queue.enqueueWriteBuffer(b_records, CL_TRUE, 0, sizeof(head), head), "clear the guide record count");
    guide.header.dims[3] = int(capacity);
    guide.header.inv_cell.w = records ? 1.0f : 0.0f;
    upload_guide();
  }
  bind_stage_args(buf, plan);

  LoopState s;
  s.n_q[ST_Q_FREE] = plan.Q;
  s.batch_done.assign(plan.ring, 0);
  s.batches_target = plan.n_batches;
  const std::vector<uint32_t> zeros(ST_C_COUNT, 0u);
  auto t_loop = Clock::now();
  if (opt.loop_started) opt.loop_started->store(true);
  while (s.accumulated < s.batches_target) {
    if (!begin_iteration(s, plan, sample_begin)) break;
    ST_CL_CHECK(ds.queue.enqueueReadBuffer(buf.counters, CL_TRUE, 0, s.counters.size() * 4, s.counters.data()), "read counters");
    ST_CL_CHECK(ds.queue.enqueueWriteBuffer(buf.counters, CL_FALSE, 0, zeros.size() * 4, zeros.data()), "reset counters");
    if (records) drain_records(*records);
    launcher->collect_profiling();
    res.stats.iterations++;
    fold_counters(s, plan, res.stats);
    accumulate_finished(s, plan, res);
    if (opt.progress) {  // finished paths, the accumulated batches' and those in flight: smooth within batches
      uint64_t paths = s.samples_done * plan.npix * plan.nch;
      for (uint64_t d : s.batch_done) paths += d;
      opt.progress(std::min(1.0, double(paths) / double(plan.total_paths)));
    }
  }
  ST_CL_CHECK(ds.queue.finish(), "finish stage loop");
  res.seconds_render = seconds_since(t_loop);  // the stage loop alone (kernel JIT is in seconds_build)
  read_film(buf, plan, s, res);
  launcher->collect_profiling();
  float mt;
  std::memcpy(&mt, &s.max_bits, 4);
  res.stats.max_throughput = mt;
  res.stats.kernels = launcher->times();
  return res;
}

Renderer::Renderer(const SceneDesc& scene, const RenderOptions& options) : impl_(new Impl) {
  impl_->scene = scene;
  impl_->opt = options;
  impl_->setup();
}
Renderer::~Renderer() = default;

RenderResult Renderer::render() { return impl_->render(impl_->settings.sample_begin, impl_->settings.spp); }
RenderResult Renderer::render(int64_t sample_begin, int spp) { return impl_->render(sample_begin, spp); }
const std::string& Renderer::device_name() const { return impl_->ds.dev.name; }
uint32_t Renderer::features() const { return impl_->ds.packed.features; }
const SceneDesc& Renderer::scene() const { return impl_->scene; }
const RenderSettings& Renderer::settings() const { return impl_->settings; }
DeviceScene& Renderer::device_scene() { return impl_->ds; }

}  // namespace spectrack
