// batch_plan.cpp: how one render's paths are cut into batches of whole samples per pixel (the
// path slots, the batch ring, the shadow-ray entries), what that takes in memory (checked before
// anything large is allocated, memory_budget.h), the device buffers and the stage kernels'
// arguments.
#include "integrator/renderer_impl.h"

#include <fmt/format.h>

#include <algorithm>
#include <cstring>
#include <iostream>

namespace spectrack {

namespace {

// What sizes the buffers of path slots and shadow rays, for messages: the options given
// (--path-slots, --shadow-ring) are named, so that a refusal says which one to lower.
std::string slot_cause(const RenderOptions& opt, const BatchPlan& p, bool shadows) {
  std::string s = opt.path_slots ? fmt::format("--path-slots {}", p.Q) : fmt::format("{} path slots", p.Q);
  if (shadows)
    s += fmt::format(" x {} light(s) x {}", p.NL / std::max<uint64_t>(1, p.shadow_ring),
                     opt.shadow_ring ? fmt::format("--shadow-ring {}", p.shadow_ring)
                                         : fmt::format("shadow ring {}", p.shadow_ring));
  return s;
}

}  // namespace

BatchPlan Renderer::Impl::plan_batches(int spp) const {
  BatchPlan p;
  // the shadow ring (types.h): 2 by default, which removes most waiting where shadow rays take
  // several launches and costs nothing measurable where they do not (bench/RESULTS.md, "No
  // waiting paths")
  const int ring = opt.shadow_ring.value_or(kDefaultShadowRing);
  if (ring < 1 || ring > ST_MAX_SHADOW_RING)
    throw Error(fmt::format("shadow ring {} is outside 1..{}", ring, ST_MAX_SHADOW_RING));
  p.shadow_ring = uint64_t(ring);
  p.NL = shadow_lights(ds.packed.st) * p.shadow_ring;
  p.npix = settings.adaptive ? uint64_t(active_pixels.size()) : settings.window.pixels();
  p.nch = uint64_t(settings.channels_per_sample);
  p.spp = uint64_t(spp);
  const int slots = opt.path_slots.value_or((ds.dev.type & CL_DEVICE_TYPE_GPU) ? kDefaultPathSlotsGpu : kDefaultPathSlotsCpu);
  if (slots < 1) throw Error(fmt::format("path slots {}: at least 1 path must be in flight", slots));
  p.Q = uint64_t(slots);
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
  uint64_t k = uint64_t(std::max(1, opt.batches_in_flight.value_or(ST_MAX_BATCHES_IN_FLIGHT)));
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
  r.path_bytes = sizeof(st_path) + p.NL * sizeof(st_shadow) + (settings.guiding ? guide_record_buffer_bytes(1, true, false, guide.header.guided_depth) : 0);
  r.queue_words = queue_words_per_slot(p.NL);
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
      opt.path_slots || opt.shadow_ring
          ? fmt::format("{}{}{}", opt.path_slots ? "a lower --path-slots" : "",
                        opt.path_slots && opt.shadow_ring ? " or " : "", opt.shadow_ring ? "a lower --shadow-ring" : "")
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
  // Q * NL shadow-ray entries of sizeof(st_shadow) bytes, AoS or SoA (kernels/shadow_state.h)
  b.shadows = ds.buffer(CL_MEM_READ_WRITE, p.Q * p.NL * sizeof(st_shadow), nullptr,
                        fmt::format("shadow rays ({})", slot_cause(opt, p, true)).c_str());
  // every entry starts empty: every byte 0, so every entry's state is ST_SHADOW_EMPTY (and its
  // equi-angular leg 0) in either layout; a path leaves its entries empty when it finishes
  static_assert(ST_SHADOW_EMPTY == 0, "the zero fill empties every shadow entry");
  if (p.Q * p.NL > 0)
    ST_CL_CHECK(ds.queue.enqueueFillBuffer(b.shadows, cl_uint(0), 0, p.Q * p.NL * sizeof(st_shadow)),
                "clear the shadow-ray entries");
  ST_CL_CHECK(ds.queue.finish(), "allocate render buffers");  // set-up, not seconds_render
  // two parities of every queue in table order (stage_table.h): Q path slots or Q * NL shadow rays
  const uint64_t per_parity = p.Q * queue_words_per_slot(p.NL) / 2;
  std::vector<uint32_t> init_queue(2 * per_parity, 0u);
  for (uint64_t i = 0; i < p.Q; ++i) init_queue[i] = uint32_t(i);  // parity 0, FREE: every slot
  // the per-pixel work counters follow the queues (queues.h pixel_work_offset), then adaptive
  // sampling's list of entries: pixel, sample offset (active_pixels_offset)
  if (ds.packed.features & ST_FEATURE_PIXEL_WORK) init_queue.resize(2 * per_parity + settings.window.pixels(), 0u);
  if (settings.adaptive)
    for (size_t j = 0; j < active_pixels.size(); ++j) {
      init_queue.push_back(active_pixels[j]);
      init_queue.push_back(active_offsets[j]);
    }
  b.queues = ds.buffer(CL_MEM_READ_WRITE, init_queue.size() * 4, init_queue.data(),
                       fmt::format("queues ({})", slot_cause(opt, p, true)).c_str());
  std::vector<uint32_t> counters(ST_C_COUNT, 0u);
  b.counters = ds.buffer(CL_MEM_READ_WRITE, counters.size() * 4, counters.data(), "counters");
  b.loop = ds.buffer(CL_MEM_READ_WRITE, sizeof(st_loop), nullptr, "loop state");
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
  for (const Stage* s : launched_stages()) {
    cl::Kernel& k = launcher->kernel(s->kernel);
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
    k.setArg(ST_ARG_LOOP, b.loop);
    k.setArg(ST_ARG_GUIDE, b_guide);
    k.setArg(ST_ARG_GUIDE_RECORDS, b_records);
  }
  cl::Kernel& acc = launcher->kernel("k_accumulate");
  acc.setArg(0, b.results);
  acc.setArg(1, b.film);
  acc.setArg(2, b.loop);
  acc.setArg(3, cl_uint(p.npix));
  acc.setArg(4, cl_uint(p.nch));
  acc.setArg(5, cl_uint(p.L));
  acc.setArg(6, cl_uint(p.moments));
  cl::Kernel& adv = launcher->kernel("k_advance");
  adv.setArg(0, b.loop);
  adv.setArg(1, b.counters);
  adv.setArg(2, cl_uint(sizeof(st_loop)));
}

}  // namespace spectrack
