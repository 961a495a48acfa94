// stage_loop.cpp: the stage loop's host side. The device holds the loop's state (kernels/
// wavefront.h): every iteration is the stage launches, k_advance (one work-item: it folds the
// counters, marks completed batches and writes the next iteration's queue sizes) and k_accumulate
// (the marked batches onto the film). The host only launches: it enqueues a chunk of iterations,
// then a non-blocking read of the state, and on a GPU waits for the read of the chunk before (so
// the device always has a chunk queued; on a CPU device for its own), then looks at the state for
// progress, the end and errors. The chunk
// grows to about kChunkSeconds of device time, so a stop request or the time limit takes effect
// within two chunks (about half a second); the guide's training passes (one iteration's records
// at a time), the film watch (it looks after each new batch) and the queue trace run one
// iteration per read instead. Every stage is launched over launch_items() work-items whatever its
// queue's size (loop_policy.h: by device type); a kernel's work-items take the items its queue
// holds, strided or in runs (kernels/wavefront.h, ST_FOR_QUEUE_ITEMS). The sized loop
// (SPECTRACK_LOOP=sized, for measurements) reads the state after every iteration instead and
// launches each stage over its queue's items.
#include <fmt/format.h>

#include <algorithm>
#include <cstring>
#include <iostream>

#include "integrator/renderer_impl.h"

namespace spectrack {

namespace {

constexpr double kChunkSeconds = 0.25;   // device time per chunk of iterations, at most
constexpr uint64_t kMaxChunk = 256;      // iterations per chunk, at most
constexpr uint64_t kMinChunk = 8;        // unless 8 iterations take more than 4 kChunkSeconds

bool trace_queues() {
  static const bool trace = [] {
    const char* e = std::getenv("SPECTRACK_TRACE_QUEUES");
    return e && std::string(e) != "0";
  }();
  return trace;
}

void trace_iteration(const st_loop& d) {
  std::string q;
  for (const Stage& s : kStages) q += fmt::format(" {} {}", s.name, d.n_q[s.queue]);
  std::cerr << fmt::format("iteration {}: issued {}{} accumulated {} status {}\n", d.iterations, d.issued, q,
                           d.accumulated, d.status);
}

// The next chunk's iterations, from the last one's device time per iteration: about
// kChunkSeconds of work, at least kMinChunk where those stay under 4 kChunkSeconds, and at most
// a quarter of the iterations run so far (beyond kMinChunk) and the iterations the finished paths'
// rate predicts are left after the chunk in flight, since the iterations enqueued after the
// last one with work run empty (their launches return at once, yet cost a few microseconds each
// on a GPU and tens on a CPU device).
uint64_t next_chunk(uint64_t chunk, double seconds, uint64_t iterations, uint64_t iterations_run, double left) {
  uint64_t k = chunk + kMinChunk;
  if (iterations > 0 && seconds > 0) {
    const double per_iteration = std::max(1e-7, seconds / double(iterations));
    k = uint64_t(kChunkSeconds / per_iteration);
    if (k < kMinChunk && double(kMinChunk) * per_iteration <= 4 * kChunkSeconds) k = kMinChunk;
    k = std::min(k, 2 * chunk + kMinChunk);
  }
  k = std::min(k, std::max(kMinChunk, iterations_run / 4));
  if (left >= 0) k = std::min(k, std::max(kMinChunk, uint64_t(left)));
  return std::clamp<uint64_t>(k, 1, kMaxChunk);
}

// Paths finished so far: those of the batches on the film and those of the batches in flight.
uint64_t paths_finished(const st_loop& d) {
  uint64_t n = uint64_t(d.samples_done) * d.paths_per_sample;
  for (uint32_t r = 0; r < d.ring; ++r) n += d.batch_done[r];
  return n;
}

}  // namespace

std::vector<const Stage*> Renderer::Impl::launched_stages() const {
  std::vector<const Stage*> v;
  for (const Stage& s : kStages)
    if (stage_launched(s, ds.packed.features, int(shadow_lights(ds.packed.st)))) v.push_back(&s);
  return v;
}

// The policy's work-items (loop_policy.h): a GPU filled several times over, a few work-groups per
// core on a CPU device; each strides over or takes a run of the rest.
size_t Renderer::Impl::launch_items(uint64_t capacity) const {
  return size_t(chunk_launch_items(loop_policy, ds.dev.compute_units, KernelLauncher::kLocalSize, capacity));
}

// The plan into the device's loop state, and the first k_advance (it issues the first paths).
void Renderer::Impl::start_loop(const RenderBuffers& b, const BatchPlan& p, LoopState& s, int64_t sample_begin) {
  st_loop& d = s.dev;
  d = st_loop{};
  d.it.batch_paths = cl_uint(p.batch_paths);
  d.it.sample_begin = cl_uint(sample_begin);
  d.it.samples_per_batch = cl_uint(p.samples_per_batch);
  d.total_paths = p.total_paths;
  d.Q = cl_uint(p.Q);
  d.ring = cl_uint(p.ring);
  d.batch_paths = cl_uint(p.batch_paths);
  d.samples_per_batch = cl_uint(p.samples_per_batch);
  d.spp = cl_uint(p.spp);
  d.paths_per_sample = cl_uint(p.npix * p.nch);
  d.batches_target = cl_uint(p.n_batches);
  d.batches_issuable = cl_uint(std::min<uint64_t>(s.batches_issuable, p.n_batches));
  d.n_q[ST_Q_FREE] = cl_uint(p.Q);
  d.status = ST_LOOP_RUNNING;
  ST_CL_CHECK(ds.queue.enqueueWriteBuffer(b.loop, CL_TRUE, 0, sizeof(st_loop), &d), "write the loop state");
  s.sized = loop_policy.sized;
  s.lockstep = s.lockstep || s.sized || trace_queues();
  s.chunk = s.lockstep ? 1 : kMinChunk;
  launcher->launch("k_advance", 1);
  if (!s.sized) {
    launcher->launch("k_accumulate", launch_items(p.npix));
    return;
  }
  // sized: the first iteration's launches need the state the first k_advance wrote
  ST_CL_CHECK(ds.queue.enqueueReadBuffer(b.loop, CL_TRUE, 0, sizeof(st_loop), &d), "read the loop state");
  s.host_waits++;
}

// n iterations: the stages this scene has, k_advance, k_accumulate. Sized (one iteration): each
// stage over the items its queue holds in the state last read, none when empty, and k_accumulate
// after the read, where the state marks batches (see_loop).
void Renderer::Impl::enqueue_iterations(const BatchPlan& p, const LoopState& s, uint64_t n) {
  const std::vector<const Stage*> stages = launched_stages();
  for (uint64_t i = 0; i < n; ++i) {
    for (const Stage* st : stages)
      launcher->launch(st->kernel, s.sized ? stage_items(&s.dev.it, st->queue)
                                           : launch_items(queue_capacity(*st, p.Q, p.NL)));
    launcher->launch("k_advance", 1);
    if (!s.sized) launcher->launch("k_accumulate", launch_items(p.npix));
  }
}

bool Renderer::Impl::stop_requested(LoopState& s) const {
  if (opt.stop && opt.stop->load()) return true;
  if (opt.deadline && Clock::now() >= *opt.deadline) {
    s.time_limit_reached = true;
    return true;
  }
  return false;
}

// One read of the device's loop state: errors, the first pass, progress, the watch. False: the
// loop is over (every batch on the film, or the watch stopped it).
bool Renderer::Impl::see_loop(const RenderBuffers& b, const BatchPlan& p, LoopState& s, const st_loop& d,
                              RenderResult& res, std::vector<st_guide_record>* records) {
  if (trace_queues()) trace_iteration(d);  // before the checks: a failed state is traced too
  if (d.status == ST_LOOP_LAYOUT) throw Error("internal: the host's and the device's loop state differ in layout");
  if (d.status == ST_LOOP_SLOTS_LOST)
    throw Error(fmt::format("internal: the path queues do not hold all {} slots after iteration {}", p.Q, d.iterations));
  if (d.status == ST_LOOP_STALLED)
    throw Error(fmt::format("internal: wavefront stalled with {} of {} batches accumulated", d.accumulated,
                            d.batches_target));
  if (records) drain_records(*records);
  if (s.sized && d.acc_first != d.acc_end) launcher->launch("k_accumulate", launch_items(p.npix));
  const uint64_t before = s.accumulated;
  s.dev = d;
  s.accumulated = d.accumulated;
  s.samples_done = d.samples_done;
  if (before == 0 && s.accumulated > 0) res.seconds_first_pass = seconds_since(t_created);
  if (opt.progress) {  // finished paths, the accumulated batches' and those in flight: smooth within batches
    uint64_t paths = (s.samples_before + s.samples_done) * p.npix * p.nch;
    for (uint64_t r = 0; r < p.ring; ++r) paths += d.batch_done[r];
    opt.progress(std::min(1.0, double(paths) / double((s.samples_before + p.spp) * p.npix * p.nch)));
  }
  if (d.status == ST_LOOP_DONE) return false;
  FilmWatch* watch = records ? nullptr : opt.watch;
  if (watch && s.accumulated > before && watch_film(b, p, s, res)) return false;
  if (d.batches_issuable != std::min<uint64_t>(s.batches_issuable, p.n_batches)) {  // the watch moved it
    const cl_uint issuable = cl_uint(std::min<uint64_t>(s.batches_issuable, p.n_batches));
    ST_CL_CHECK(ds.queue.enqueueWriteBuffer(b.loop, CL_FALSE, offsetof(st_loop, batches_issuable), sizeof(cl_uint),
                                            &issuable),
                "write the issuable batches");
    s.dev.batches_issuable = issuable;
    // a loop waiting for the host starts again (k_advance folds nothing: no iteration ran)
    if (d.status == ST_LOOP_WAITING) {
      launcher->launch("k_advance", 1);
      if (s.sized) {  // the next launches are sized by the state that k_advance writes
        ST_CL_CHECK(ds.queue.enqueueReadBuffer(b.loop, CL_TRUE, 0, sizeof(st_loop), &s.dev), "read the loop state");
        s.host_waits++;
      }
    }
  } else if (d.status == ST_LOOP_WAITING) {
    throw Error(fmt::format("internal: wavefront stalled with {} of {} batches accumulated (the watch allows no more)",
                            d.accumulated, d.batches_target));
  }
  return true;
}

// The loop: chunks of iterations, each followed by a non-blocking read of the state; the host
// waits for the read of the chunk before while the device runs the next (lockstep: for its own).
void Renderer::Impl::drive_loop(const RenderBuffers& b, const BatchPlan& p, LoopState& s, RenderResult& res,
                                std::vector<st_guide_record>* records) {
  st_loop* read = s.reads;  // in LoopState: a read still queued when this returns lands there
  cl::Event ev[2];
  int pending = -1;  // the read not looked at yet
  uint64_t chunk_of[2] = {0, 0};
  cl_ulong t_last = 0, t_first = 0;  // device clock at the end of the last and the first read looked at
  uint64_t iterations_first = 0;      // iterations run at the first
  uint64_t finished_last = 0, iterations_last = 0;  // at the last read looked at
  // where the loop starts (a resumed film's samples): the reporter's first line, before the first
  // chunk's paths finish, and the start of its rate
  if (opt.progress) opt.progress(double(s.samples_before + s.samples_done) / double(s.samples_before + p.spp));
  for (int next = 0;; next = 1 - next) {
    if (stop_requested(s)) break;
    enqueue_iterations(p, s, s.chunk);
    chunk_of[next] = s.chunk;
    ST_CL_CHECK(ds.queue.enqueueReadBuffer(b.loop, CL_FALSE, 0, sizeof(st_loop), &read[next], nullptr, &ev[next]),
                "read the loop state");
    ST_CL_CHECK(ds.queue.flush(), "flush the stage loop");
    // a CPU device shares the host's memory and cores: its reads cost microseconds, and a chunk
    // queued ahead would only add empty iterations at the end
    const bool ahead = !s.lockstep && (ds.dev.type & CL_DEVICE_TYPE_GPU) != 0;
    const int look = ahead ? pending : next;
    pending = ahead ? next : -1;
    if (look < 0) continue;
    ST_CL_CHECK(ev[look].wait(), "wait for the loop state");
    s.host_waits++;
    launcher->collect_profiling();
    cl_ulong t_end = 0;  // the chunk's device time: from the read before to this one
    const bool timed = ev[look].getProfilingInfo(CL_PROFILING_COMMAND_END, &t_end) == CL_SUCCESS && t_last > 0;
    double seconds = timed && t_end > t_last ? double(t_end - t_last) * 1e-9 : 0.0;
    t_last = t_end;
    if (t_first == 0) {
      t_first = t_end;
      iterations_first = read[look].iterations;
    } else if (read[look].iterations > iterations_first) {  // the chunk's time or the mean so far, the longer
      const double mean = double(t_end - t_first) * 1e-9 / double(read[look].iterations - iterations_first);
      seconds = std::max(seconds, mean * double(chunk_of[look]));
    }
    if (!see_loop(b, p, s, read[look], res, records)) break;
    // iterations left after the chunk in flight, at the rate the last chunk finished paths
    const uint64_t finished = paths_finished(s.dev);
    const double rate = s.dev.iterations > iterations_last
                            ? double(finished - finished_last) / double(s.dev.iterations - iterations_last)
                            : 0.0;
    const double left = rate > 0 ? double(s.dev.total_paths - finished) / rate - double(ahead ? chunk_of[1 - look] : 0)
                                 : -1.0;
    finished_last = finished;
    iterations_last = s.dev.iterations;
    if (!s.lockstep) s.chunk = next_chunk(s.chunk, seconds, chunk_of[look], s.dev.iterations, left);
  }
}

// The device's sums and occupancy into the render's statistics.
void Renderer::Impl::loop_stats(const BatchPlan& p, const LoopState& s, RenderStats& S) const {
  const st_loop& d = s.dev;
  S.iterations = d.iterations;
  S.iterations_below_half = d.below_half;
  S.host_waits = s.host_waits;
  S.occupancy_mean = d.iterations ? double(d.busy_sum) / (double(d.iterations) * double(p.Q)) : 0.0;
  S.occupancy_min = double(d.busy_min) / double(p.Q);
  S.paths = s.samples_done * p.npix * p.nch;
  int k = 0;
#define ST_X_LOOP_SUM(E, field, key) S.field = d.sums[k++];
  ST_SUM_COUNTERS(ST_X_LOOP_SUM)
#undef ST_X_LOOP_SUM
  float mt;
  std::memcpy(&mt, &d.max_bits, 4);
  S.max_throughput = mt;
}

}  // namespace spectrack
