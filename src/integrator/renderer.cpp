// renderer.cpp: the wavefront stage loop on one device (see renderer.h for the design).
// Set-up: take the resolved settings (integrator/settings.h), pack the scene (scene/scene_pack.h), choose
// the device and upload (device/device_scene.h), build the kernels (cached) for the scene's
// st_feature mask (--generic-kernels: every feature and ST_MAX_MEDIA media). A render is then a
// few named steps: plan the batches, check the memory, allocate, bind the stage arguments, run the
// iterations (stage_loop.cpp: the device keeps the queue sizes, folds the counters and adds finished
// batches to the film; the host enqueues chunks of iterations and reads the loop state between
// them), read the film back. What a scene lacks costs nothing: a scene without
// lights gets no shadow-ray buffer or queue, and one whose escaping rays see no light gets no
// escape launch (track sends them straight to finish). With guiding, the first render trains the
// guide cache (docs/guiding.md): a pass over the full film with random streams of their own, whose
// radiance records are drained after every iteration and fitted on the host, and whose samples are
// the sequence's first (settings.h guide_training_samples: kept by the renders whose range holds
// them); the render's own samples follow, with the cache, its training time counted in seconds_render.
#include "integrator/renderer_impl.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <iostream>

#include "guiding/guide_cache.h"
#include "device/device_scene.h"
#include "integrator/film_watch.h"
#include "integrator/memory_budget.h"
#include "integrator/loop_policy.h"
#include "integrator/state_layout.h"
#include "util/phase.h"

namespace spectrack {

void Renderer::Impl::setup() {
  auto t0 = Clock::now();
  set_phase("scene packing (volumes, environment maps and their CDFs, majorant grids)");
  PackedScene packed = pack_scene(scene, settings, pack_options(settings));
  // the feature mask is in the source, hence in the kernel-cache key
  if (opt.generic_kernels) packed.features = ST_FEATURES_ALL;
  packed.features |= opt.feature_floor & uint32_t(ST_FEATURES_ALL);
  if (settings.guiding) packed.features |= ST_FEATURE_GUIDING;
  if (settings.adaptive) packed.features |= ST_FEATURE_ADAPTIVE;
  // the per-pixel work counters, for the adaptive trace only (adaptive.cpp SPECTRACK_ADAPTIVE_PIXELS)
  if (settings.adaptive && std::getenv("SPECTRACK_ADAPTIVE_PIXELS")) packed.features |= ST_FEATURE_PIXEL_WORK;
  const int max_media = opt.generic_kernels ? ST_MAX_MEDIA : std::max(1, packed.st.n_media);
  std::vector<std::pair<std::string, std::string>> defines = {
      {"ST_KERNEL_MAX_MEDIA", std::to_string(max_media)}, {"ST_FEATURES", fmt::format("0x{:x}u", packed.features)}};
  set_phase("device upload and kernel build");
  ds = upload_scene(opt.device, std::move(packed), std::move(defines));
  state_layout = choose_state_layout(ds.dev.type);  // the path state's layout (kernel define)
  add_state_layout_define(state_layout, ds.defines);
  loop_policy = choose_loop_policy(ds.dev.type);  // the stage loop's launches (item order: a kernel define)
  add_loop_policy_define(loop_policy, ds.defines);
  // guiding off: a header of zeros (nothing guides, nothing records); the kernels compiled without
  // ST_FEATURE_GUIDING never read it
  if (settings.guiding) {
    guide = make_guide_cache(ds.packed.st, opt.guide_grid_cells > 0 ? opt.guide_grid_cells : kGuideGridCells);
    guide.header.guided_depth = guide_depth_setting(opt.guide_depth);
    guide.header.phase_product = guide_phase_product_setting(guide.header.guided_depth) ? 1 : 0;
    guide.full_path = guide_full_path_setting(guide.header.phase_product != 0);
    guide.fixed_alpha = opt.guide_alpha >= 0 ? opt.guide_alpha : guide_alpha_setting();
  }
  std::vector<unsigned char> g = guide.serialize();
  if (settings.guiding) g.resize(guide.capacity_bytes(), 0);  // room for the regions refinement adds
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
// kernel the renders launch, at the real work-group size, moves it here, into seconds_build.
// Every item returns at once without touching memory but a loop state of zeros: its queue sizes
// are 0 and it marks no batch for k_accumulate; k_advance sees a size that is not its own and
// only marks that state.
void Renderer::Impl::warm_kernels() {
  const cl::Buffer none = ds.buffer(CL_MEM_READ_WRITE, 16, nullptr, "warm-up");
  const std::vector<unsigned char> zeros(sizeof(st_loop), 0);
  const cl::Buffer idle = ds.buffer(CL_MEM_READ_WRITE, zeros.size(), zeros.data(), "warm-up loop state");
  for (const Stage* s : launched_stages()) {
    cl::Kernel& k = launcher->kernel(s->kernel);
    k.setArg(ST_ARG_SCENE, ds.b_scene);
    k.setArg(ST_ARG_GRIDS, ds.b_grids);
    k.setArg(ST_ARG_MAJORANTS, ds.b_maj);
    k.setArg(ST_ARG_ENV, ds.b_env);
    for (int a : {ST_ARG_PATHS, ST_ARG_SHADOWS, ST_ARG_QUEUES, ST_ARG_COUNTERS, ST_ARG_RESULTS, ST_ARG_GUIDE,
                  ST_ARG_GUIDE_RECORDS})
      k.setArg(a, none);
    k.setArg(ST_ARG_SLOTS, cl_uint(0));
    k.setArg(ST_ARG_LIGHTS, cl_uint(0));
    k.setArg(ST_ARG_LOOP, idle);
    launcher->warm(s->kernel);
  }
  cl::Kernel& acc = launcher->kernel("k_accumulate");
  acc.setArg(0, none);
  acc.setArg(1, none);
  acc.setArg(2, idle);
  for (int a = 3; a < 7; ++a) acc.setArg(a, cl_uint(0));
  launcher->warm("k_accumulate");
  cl::Kernel& adv = launcher->kernel("k_advance");
  adv.setArg(0, idle);
  adv.setArg(1, none);
  adv.setArg(2, cl_uint(0));
  launcher->warm("k_advance");
  ST_CL_CHECK(ds.queue.finish(), "kernel warm-up");
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
  res.light_sampling_used = st_light_sampling(ds.packed.st.light_sampling);
  res.equiangular_used = ds.packed.st.equiangular.n_local > 0;
  res.iteration_budget = settings.iteration_budget;
  res.majorants = ds.packed.majorants;
  return res;
}

// The work counters (queues.h pixel_work_add) of the render's pixels, in the order of its pixel list.
void Renderer::Impl::read_pixel_work(const RenderBuffers& b, const BatchPlan& p, RenderResult& res) {
  if (!(ds.packed.features & ST_FEATURE_PIXEL_WORK)) return;
  const uint64_t window = settings.window.pixels(), at = p.Q * queue_words_per_slot(p.NL);
  std::vector<uint32_t> work(window);
  ST_CL_CHECK(ds.queue.enqueueReadBuffer(b.queues, CL_TRUE, at * 4, window * 4, work.data()), "read the pixel work");
  res.pixel_work.resize(active_pixels.size());
  for (size_t j = 0; j < active_pixels.size(); ++j) res.pixel_work[j] = double(work[active_pixels[j]]);
}

void Renderer::Impl::read_film(const RenderBuffers& b, const BatchPlan& p, const LoopState& s, RenderResult& res) {
  const uint64_t n = s.samples_before + s.samples_done;  // a resumed film holds samples_before more
  res.spp_done = int(n);
  res.interrupted = s.samples_done < p.spp && !s.noise_target_reached;
  res.time_limit_reached = s.time_limit_reached;
  res.noise_target_reached = s.noise_target_reached;
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
      if (n > 0) res.rgb[i * 3 + k] = float(res.sum[i * 3 + k] / double(n));
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
    if (settings.aovs & ST_AOV_BIT(SHADOW))  // a shadow catcher's shadowed, then unshadowed estimates
      for (int l : {ST_RESULT_SHADOW, ST_RESULT_UNSHADOWED})
        for (int k = 0; k < 3; ++k) res.aov_sum[i * na + a++] = layer(l, i, k);
    if (settings.aovs & (ST_AOV_BIT(ALBEDO) | ST_AOV_BIT(DEPTH)))
      res.aov_sum[i * na + a++] = layer(ST_RESULT_ALPHA, i, 3);  // how many of them collided
  }
}

RenderResult Renderer::Impl::render(int64_t sample_begin, int spp) {
  if (sample_begin < 0 || spp < 1 || uint64_t(sample_begin) + uint64_t(spp) > (uint64_t(1) << 32))
    throw Error(fmt::format("sample range {}:{} is not a non-empty range of sample indices 0 .. 2^32",
                            sample_begin, sample_begin + spp));
  if (settings.adaptive && active_pixels.empty()) {  // a render of every pixel (Renderer::render)
    active_pixels.resize(settings.window.pixels());
    for (size_t i = 0; i < active_pixels.size(); ++i) active_pixels[i] = uint32_t(i);
    active_offsets.assign(active_pixels.size(), 0u);
  }
  const std::clock_t cpu0 = std::clock();
  const double seconds_training = settings.guiding && !guide_trained ? train_guide() : 0.0;
  // With guiding the sequence's first T samples are the training passes' (guide_samples), and
  // sample i >= T is the render's own sample i - T (settings.h guide_training_samples).
  // (a cache read from --guide-cache's file renders them when a range first holds them)
  const int64_t T = guide_loaded ? settings.guide_training_samples : guide_samples.spp_done, end = sample_begin + spp;
  const bool with_training = sample_begin < T;
  if (with_training && (sample_begin != 0 || end < T))
    throw Error(fmt::format("internal: samples {}:{} cut the guide's training samples 0:{}", sample_begin, end, T));
  if (with_training && guide_loaded && guide_samples.spp_done == 0) render_training_samples();
  const int64_t own_begin = std::max(sample_begin, T) - T, own_end = end - T;
  watch_with_training = with_training && guide_samples.spp_done > 0;  // a noise target counts them
  RenderResult res = own_end > own_begin ? run_stage_loop(own_begin, int(own_end - own_begin), nullptr)
                                         : empty_film(own_begin);
  watch_with_training = false;
  if (with_training) add_guide_samples(res);  // with their statistics
  res.sample_begin = sample_begin;
  res.spp_requested = spp;
  res.seconds_render += seconds_training;  // efficiency counts the training
  res.cpu_seconds_render = double(std::clock() - cpu0) / CLOCKS_PER_SEC;
  res.guide = guide_info;
  return res;
}

// A render of no sample of its own (a shard that holds only the guide's training samples): the
// window's film of zeros, every layer.
RenderResult Renderer::Impl::empty_film(int64_t sample_begin) const {
  RenderResult res = result_header(sample_begin, 0);
  const uint64_t npix = settings.adaptive ? uint64_t(active_pixels.size()) : settings.window.pixels();
  res.aov_channels = aov_sum_channels(settings.aovs);
  res.rgb.assign(npix * 3, 0.0f);
  res.sum.assign(npix * 3, 0.0);
  res.aov_sum.assign(npix * res.aov_channels.size(), 0.0);
  return res;
}

RenderResult Renderer::Impl::run_stage_loop(int64_t sample_begin, int spp, std::vector<st_guide_record>* records) {
  RenderResult res = result_header(sample_begin, spp);
  launcher->times().clear();
  FilmWatch* watch = records ? nullptr : opt.watch;  // training passes are not watched
  const FilmState* resumed = watch ? watch->resume() : nullptr;
  const int64_t before = resumed ? resumed->samples_done : 0;
  if (resumed && (resumed->sample_begin != sample_begin || before < 1 || before >= spp))
    throw Error(fmt::format("internal: a film of samples {}:{} resumed in a render of samples {}:{}",
                            resumed->sample_begin, resumed->sample_begin + before, sample_begin, sample_begin + spp));
  BatchPlan plan = plan_batches(int(spp - before));
  // the default shadow ring falls back to one entry per (path, light) where two would not fit (the
  // image is the same; paths may wait for their shadow rays)
  if (!opt.shadow_ring && plan.shadow_ring > 1 && memory_need(plan).device > double(ds.dev.global_mem)) {
    plan.shadow_ring = 1;
    plan.NL = shadow_lights(ds.packed.st);
  }
  check_memory(plan);  // refuse what cannot fit before allocating anything
  res.path_slots = plan.Q;
  res.shadow_ring = plan.shadow_ring;
  res.state_layout = state_layout_name(state_layout);
  res.batches_in_flight = plan.ring;
  set_phase("film allocation");
  set_ring_size(plan.ring);
  RenderBuffers buf = allocate(plan);
  if (settings.guiding) {  // training: records on, vertex rings, one iteration's records
    const uint64_t capacity = records ? guide_record_capacity(plan.Q, guide.header.guided_depth) : 0;
    const uint32_t head[4] = {0, 0, 0, 0};
    b_records = ds.buffer(CL_MEM_READ_WRITE, guide_record_buffer_bytes(plan.Q, records != nullptr, guide.header.split_max > 0,
                                                                    guide.header.guided_depth),
                          nullptr, "guide records");
    ST_CL_CHECK(ds.queue.enqueueWriteBuffer(b_records, CL_TRUE, 0, sizeof(head), head), "clear the guide record count");
    guide.header.dims[3] = int(capacity);
    const int64_t film_pixels = int64_t(settings.full_width) * settings.full_height;  // a pass's fraction: of the full film
    guide.header.inv_cell.w = records ? guide_record_fraction(film_pixels, spp, guide_record_samples()) : 0.0f;
    upload_guide();
  }
  bind_stage_args(buf, plan);
  if (resumed) load_film_state(buf, plan, *resumed);

  LoopState s;
  s.samples_before = uint64_t(before);
  s.lockstep = records != nullptr || watch != nullptr;
  if (watch) limit_issue(s, plan, *watch);
  auto t_loop = Clock::now();
  if (opt.loop_started) opt.loop_started->store(true);
  start_loop(buf, plan, s, sample_begin + before);
  drive_loop(buf, plan, s, res, records);
  ST_CL_CHECK(ds.queue.enqueueReadBuffer(buf.loop, CL_TRUE, 0, sizeof(st_loop), &s.dev), "read the loop state");
  s.host_waits++;
  res.seconds_render = seconds_since(t_loop);  // the stage loop alone (kernel JIT is in seconds_build)
  s.accumulated = s.dev.accumulated;
  s.samples_done = s.dev.samples_done;
  if (s.accumulated > 0 && res.seconds_first_pass == 0) res.seconds_first_pass = seconds_since(t_created);
  loop_stats(plan, s, res.stats);
  read_film(buf, plan, s, res);
  read_pixel_work(buf, plan, res);
  if (watch && watch->wants_final_state()) watch->final_state(film_state(buf, plan, s, sample_begin));
  launcher->collect_profiling();
  res.stats.kernels = launcher->times();
  return res;
}

Renderer::Renderer(const SceneDesc& scene, const RenderOptions& options)
    : Renderer(scene, resolve_settings(scene, options), options) {}
Renderer::Renderer(const SceneDesc& scene, const RenderSettings& settings, const RenderOptions& options)
    : impl_(new Impl) {
  impl_->scene = scene;
  impl_->opt = options;
  impl_->settings = settings;
  impl_->setup();
}
Renderer::~Renderer() = default;

RenderResult Renderer::render() { return impl_->render(impl_->settings.sample_begin, impl_->settings.spp); }
RenderResult Renderer::render(int64_t sample_begin, int spp) { return impl_->render(sample_begin, spp); }
RenderResult Renderer::render_pixels(const std::vector<uint32_t>& window_pixels, int64_t sample_begin, int spp,
                                     const std::vector<uint32_t>& sample_offsets) {
  if (!impl_->settings.adaptive) throw Error("internal: a render of a pixel list without adaptive sampling");
  if (window_pixels.empty()) throw Error("internal: a render of no pixel");
  if (!sample_offsets.empty() && sample_offsets.size() != window_pixels.size())
    throw Error("internal: a pixel list's sample offsets do not match its pixels");
  for (uint32_t p : window_pixels)
    if (p >= impl_->settings.window.pixels()) throw Error(fmt::format("internal: pixel {} outside the window", p));
  const uint32_t last = sample_offsets.empty() ? 0u : *std::max_element(sample_offsets.begin(), sample_offsets.end());
  if (sample_begin < 0 || spp < 1 || uint64_t(sample_begin) + last + uint64_t(spp) > (uint64_t(1) << 32))
    throw Error(fmt::format("internal: samples {}:{} of a pixel list with offsets up to {} are not sample indices 0 .. 2^32",
                            sample_begin, sample_begin + spp, last));
  impl_->active_pixels = window_pixels;
  impl_->active_offsets = sample_offsets;
  impl_->active_offsets.resize(window_pixels.size(), 0u);
  return impl_->render(sample_begin, spp);
}
const std::string& Renderer::device_name() const { return impl_->ds.dev.name; }
uint32_t Renderer::features() const { return impl_->ds.packed.features; }
const SceneDesc& Renderer::scene() const { return impl_->scene; }
const RenderSettings& Renderer::settings() const { return impl_->settings; }
DeviceScene& Renderer::device_scene() { return impl_->ds; }

}  // namespace spectrack
