// renderer_guiding.cpp: the guide's training passes (docs/guiding.md): a few passes over the full
// film with random streams of their own, whose images are dropped and whose radiance records are
// drained after every iteration and fitted on the host into the guide cache, then uploaded.
#include "integrator/renderer_impl.h"

#include <fmt/format.h>

#include <algorithm>
#include <cstring>
#include <iostream>

namespace spectrack {

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

}  // namespace spectrack
