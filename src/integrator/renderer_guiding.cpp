// renderer_guiding.cpp: the guide's training passes (docs/guiding.md): a few passes over the full
// film (whatever the render's window: every part of a render trains the same cache) with random
// streams of their own, whose window pixels are kept for the renders that hold the training
// samples and whose radiance records are drained after every iteration; after each pass the host
// refines the cache's regions where the records crowd and fits them, then uploads the cache.
#include "integrator/renderer_impl.h"

#include <fmt/format.h>

#include <algorithm>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <iostream>
#include <string>

#include "film/film.h"
#include "guiding/guide_cache_file.h"

namespace spectrack {

void Renderer::Impl::upload_guide() {
  const std::vector<unsigned char> g = guide.serialize();
  ST_CL_CHECK(ds.queue.enqueueWriteBuffer(b_guide, CL_TRUE, 0, g.size(), g.data()), "upload the guide cache");
}

// Appends the records of the last iteration (their order is the device's; the fit sorts them)
// and empties the buffer. Its capacity (guide_record_capacity) is the most one iteration records.
// One synchronisation per iteration: the count's blocking read (which also completes the previous
// drain's reads on the in-order queue, so `out` may grow); the records' read and the count's reset
// are queued without waiting, and the stage loop's final finish completes the last ones.
void Renderer::Impl::drain_records(std::vector<st_guide_record>& out) {
  static const uint32_t zero = 0;
  const auto t0 = Clock::now();
  uint32_t n = 0;
  ST_CL_CHECK(ds.queue.enqueueReadBuffer(b_records, CL_TRUE, 0, 4, &n), "read the guide record count");
  guide_info.drains++;
  if (n > uint32_t(guide.header.dims[3]))
    throw Error(fmt::format("internal: {} guide records in one iteration, above the capacity {}", n, guide.header.dims[3]));
  if (n > 0) {
    const size_t first = out.size();
    out.resize(first + n);
    ST_CL_CHECK(ds.queue.enqueueReadBuffer(b_records, CL_FALSE, 16, size_t(n) * sizeof(st_guide_record), &out[first]),
                "read the guide records");
    ST_CL_CHECK(ds.queue.enqueueWriteBuffer(b_records, CL_FALSE, 0, 4, &zero), "reset the guide record count");
  }
  guide_info.seconds_drain += seconds_since(t0);
}

int64_t Renderer::Impl::guide_record_samples() const {
  return opt.guide_record_samples >= 0 ? opt.guide_record_samples : guide_record_samples_setting();
}

// Adds a training pass's pixel means (over RGB) times its spp to `sum` (guided roulette's pixel
// estimates: their mean over the passes' samples).
static void add_pixel_estimates(std::vector<double>& sum, const RenderResult& pass, int spp) {
  for (size_t i = 0; i < sum.size() && 3 * i + 2 < pass.rgb.size(); ++i)
    sum[i] += double(pass.rgb[3 * i] + pass.rgb[3 * i + 1] + pass.rgb[3 * i + 2]) / 3.0 * double(spp);
}

// Adds a training pass's film sums (beauty and layers) and samples to `kept`.
static void keep_samples(RenderResult& kept, const RenderResult& pass) {
  if (kept.spp_done == 0) {
    kept.x0 = pass.x0, kept.y0 = pass.y0, kept.width = pass.width, kept.height = pass.height;
    kept.aov_channels = pass.aov_channels;
    kept.sum.assign(pass.sum.size(), 0.0);
    kept.aov_sum.assign(pass.aov_sum.size(), 0.0);
  }
  for (size_t i = 0; i < kept.sum.size() && i < pass.sum.size(); ++i) kept.sum[i] += pass.sum[i];
  for (size_t i = 0; i < kept.aov_sum.size() && i < pass.aov_sum.size(); ++i) kept.aov_sum[i] += pass.aov_sum[i];
  kept.spp_done += pass.spp_done;
  kept.stats.add(pass.stats);
}

// Crops a full-film result to the window's pixels (beauty and layer sums, in the window's order).
static void crop_to_window(RenderResult& r, const FilmWindow& w, int full_width) {
  if (r.spp_done == 0 || (r.x0 == w.x0 && r.y0 == w.y0 && r.width == w.width && r.height == w.height)) return;
  const size_t na = r.aov_channels.size();
  std::vector<double> sum(w.pixels() * 3), aov(w.pixels() * na);
  for (int y = 0; y < w.height; ++y)
    for (int x = 0; x < w.width; ++x) {
      const size_t i = size_t(y) * size_t(w.width) + size_t(x);
      const size_t f = size_t(y + w.y0) * size_t(full_width) + size_t(x + w.x0);
      for (int k = 0; k < 3; ++k) sum[3 * i + k] = r.sum[3 * f + k];
      for (size_t k = 0; k < na; ++k) aov[na * i + k] = r.aov_sum[na * f + k];
    }
  r.sum = std::move(sum);
  r.aov_sum = std::move(aov);
  r.rgb.clear();
  r.x0 = w.x0, r.y0 = w.y0, r.width = w.width, r.height = w.height;
}

// A render whose samples hold the training passes' adds their film sums to its own (sums of
// samples, so the image is their mean over every sample: each training sample is unbiased, its
// pass guided by a cache fitted from the passes before it alone).
void Renderer::Impl::add_guide_samples(RenderResult& res) {
  const RenderResult& g = guide_samples;
  if (g.spp_done == 0) return;
  if (g.sum.size() != res.sum.size() || g.aov_sum.size() != res.aov_sum.size())
    throw Error("internal: the training passes' film does not match the render's");
  for (size_t i = 0; i < res.sum.size(); ++i) res.sum[i] += g.sum[i];
  for (size_t i = 0; i < res.aov_sum.size(); ++i) res.aov_sum[i] += g.aov_sum[i];
  res.spp_done += g.spp_done;
  res.stats.add(g.stats);  // the passes' paths, events, iterations and kernel times
  res.rgb.assign(res.sum.size(), 0.0f);
  for (size_t i = 0; i < res.rgb.size(); ++i) res.rgb[i] = float(res.sum[i] / double(res.spp_done));
}

// The window the stage loop renders: the render's, or the full film for the training passes (the
// scene constants' window too).
void Renderer::Impl::set_window(const FilmWindow& w) {
  settings.window = w;
  ds.packed.st.pixel_x0 = w.x0;
  ds.packed.st.pixel_y0 = w.y0;
  ds.packed.st.window_width = w.width;
  ds.packed.st.window_height = w.height;
}

// A training pass's state of the renderer (the training seed in the scene constants, no progress
// reports), and on restore (or when an exception leaves the scope) the render's again: seed,
// window, progress and the cache's header.
Renderer::Impl::TrainingState::TrainingState(Impl& r)
    : r(r), seed(r.ds.packed.st.seed), window(r.settings.window), header(r.guide.header), progress(r.opt.progress) {
  r.ds.packed.st.seed = seed ^ kGuideTrainingSeed;
  r.ds.write_scene_constants();
  r.opt.progress = nullptr;
}
void Renderer::Impl::TrainingState::restore() {
  if (restored) return;
  restored = true;
  r.opt.progress = progress;
  r.ds.packed.st.seed = seed;
  r.set_window(window);
  r.ds.write_scene_constants();
}
Renderer::Impl::TrainingState::~TrainingState() {
  if (restored) return;
  r.guide.header = header;  // an exception: the cache as it was (a failed training leaves no guide)
  try {
    restore();
  } catch (...) {  // the device failed too: the exception in flight says why
  }
}

// The render's settings in the header of a trained or loaded cache (guided sampling on where a
// region guides: a cache whose learned alphas are all 0 leaves the render's paths the phase
// function without a region lookup; no records; guided roulette and splitting as asked), uploaded,
// and the cache's statistics.
void Renderer::Impl::finish_guide() {
  guide_info.regions_guided = int(std::count_if(guide.regions.begin(), guide.regions.end(),
                                                [](const st_guide_region& g) { return g.alpha > 0; }));
  guide.header.origin.w = guide_info.regions_guided > 0 ? 1.0f : 0.0f;
  guide.header.inv_cell.w = 0.0f;
  guide.header.split_max = settings.guide_splitting ? kGuideSplitMax : 0;
  guide.header.rr_below = settings.guide_splitting ? kGuideRouletteBelow : 0.0f;
  guide.header.rr_floor = settings.guide_splitting ? kGuideSurvivalFloor : 0.0f;
  upload_guide();
  guide_trained = true;
  guide_info.used = true;
  guide_info.bytes = guide.bytes();
  guide_info.regions = int(guide.regions.size());
}

// What a cache depends on (guide_cache_file.h): the scene as it shapes the image (its hash reads
// every file it references), the film, the estimator's choices and the seed, the guide's settings
// and the training's samples. Not guided roulette and splitting, which act in the render only.
nlohmann::json Renderer::Impl::guide_cache_key() const {
  const RenderIdentity id = render_identity(settings);
  nlohmann::json key = {{"scene_hash", opt.scene_json.empty() ? scene_hash(scene) : scene_hash(scene, opt.scene_json)},
          {"film", {settings.full_width, settings.full_height}},
          {"seed", id.seed},
          {"tracker", id.tracker},
          {"scheme", id.scheme},
          {"absorption", id.absorption},
          {"light_sampling", id.light_sampling},
          {"transmittance", id.transmittance},
          {"lookup", id.lookup},
          {"color", id.color},
          {"equiangular", id.equiangular},
          {"shutter", id.shutter},
          {"iteration_budget", id.iteration_budget},  // the training passes' random numbers
          {"majorant", id.majorant},
          {"ray_marching", id.ray_marching},
          {"spectrack_version", id.version},
          {"guided_depth", guide.header.guided_depth},
          {"phase_product", guide.header.phase_product},
          {"full_path", guide.full_path},
          {"fixed_alpha", guide.fixed_alpha},
          {"grid_cells", {guide.header.dims[0], guide.header.dims[1], guide.header.dims[2]}},
          {"training_samples", settings.guide_training_samples},
          {"training_schedule", guide_training_setting().spp},
          {"alpha", (settings.aovs & ST_AOV_BIT(ALPHA)) != 0},  // the pixel estimates leave out the seen environment
          {"records", kGuideRecordsVersion},
          {"record_samples", guide_record_samples()}};
  // spectral mode's wavelengths, the training passes' among them (rgb mode has none: its key is unchanged)
  if (!id.wavelength_sampling.empty()) key["wavelength_sampling"] = id.wavelength_sampling;
  return key;
}

// The cache from --guide-cache's file: no training pass here; a render whose samples hold the
// training pass's renders them for its window (render_training_samples), the same samples the
// training rendered over the full film.
double Renderer::Impl::load_guide() {
  const auto t0 = Clock::now();
  const std::clock_t cpu0 = std::clock();
  guide_info = GuideInfo{};
  guide_samples = RenderResult{};
  read_guide_cache_file(opt.guide_cache_file, guide_cache_key(), guide);
  guide_loaded = true;
  finish_guide();
  guide_info.cache_file = "read";
  guide_info.seconds_training = seconds_since(t0);
  guide_info.cpu_seconds_training = double(std::clock() - cpu0) / CLOCKS_PER_SEC;
  return guide_info.seconds_training;
}

// With a loaded cache, the training pass's samples of this render's window: the pass as it ran in
// training (the training seed, guided sampling and guided roulette off, records collected: the same
// kernels' path), its records dropped. Its film is those pixels of the training's, bit for bit.
void Renderer::Impl::render_training_samples() {
  TrainingState training(*this);
  guide.header.origin.w = 0.0f;
  guide.header.split_max = 0;
  guide.header.rr_below = guide.header.rr_floor = 0.0f;
  std::vector<st_guide_record> dropped;
  const auto t0 = Clock::now();
  guide_samples = run_stage_loop(0, settings.guide_training_samples, &dropped);
  guide_info.seconds_training_loops += seconds_since(t0);
  training.restore();
  guide.header = training.header;
  upload_guide();
}

// Measurements (SPECTRACK_GUIDE_REPORT=1): what the cache after training pass k does to a path, for
// the first medium's phase function, the lobes against the first directional light.
void Renderer::Impl::report_guide(int pass) const {
  const st_scene& st = ds.packed.st;
  const float* sun = nullptr;
  for (int l = 0; l < st.n_lights && !sun; ++l)
    if (st.lights[l].type == ST_LIGHT_DIRECTIONAL) sun = &st.lights[l].direction.x;
  const float g = st.n_media > 0 && st.media[0].phase_type == ST_PHASE_HG ? st.media[0].g : 0.0f;
  report_guide_cache(guide, g, guide.header.phase_product != 0, sun, pass);
}

// The training passes: kGuideTrainingSpp samples per pixel each, settings.guide_training_samples
// in all (samples 0-3 of a seed of their own), each guided by the cache the previous one fitted;
// records are fitted once per pass. They render the full film whatever the window, so every tile
// and shard of a render fits the same cache; the window's pixels of their film are kept. With
// adaptive sampling (never a window: settings.cpp) the passes run in the first round (the pilot),
// over every pixel in film order, so their film adds to that round's as in a plain render.
double Renderer::Impl::train_guide() {
  if (!opt.guide_cache_file.empty() && std::filesystem::exists(opt.guide_cache_file)) return load_guide();
  const FilmWindow window = settings.window, full{0, 0, settings.full_width, settings.full_height};
  if (settings.adaptive && (active_pixels.size() != size_t(settings.window.pixels()) || window.pixels() != full.pixels()))
    throw Error("internal: guide training in an adaptive round that does not cover every pixel of the film");
  auto t0 = Clock::now();
  const std::clock_t cpu0 = std::clock();
  TrainingState training(*this);
  set_window(full);
  ds.write_scene_constants();
  std::vector<st_guide_record> records;
  std::vector<double> pixel_sum(guide.pixel_estimate.size(), 0.0);
  int64_t begin = 0;
  bool interrupted = false;
  guide_info = GuideInfo{};
  guide_samples = RenderResult{};
  const GuideTraining schedule = guide_training_setting();
  // kept passes render the sequence's first settings.guide_training_samples (fewer in a render of few samples)
  const int64_t kept = settings.guide_training_samples;
  for (size_t k = 0; k < schedule.spp.size() && (!schedule.keep || begin < kept); ++k) {
    const int pass_spp = int(schedule.keep ? std::min<int64_t>(schedule.spp[k], kept - begin) : schedule.spp[k]);
    records.clear();
    const auto t_loop = Clock::now();
    const RenderResult pass = run_stage_loop(begin, pass_spp, &records);
    guide_info.seconds_training_loops += seconds_since(t_loop);
    if (opt.guide_records_hook) opt.guide_records_hook(records);
    guide_info.training_iterations += pass.stats.iterations;
    for (auto& [name, t] : pass.stats.kernels) {
      guide_info.training_kernels[name].seconds += t.seconds;
      guide_info.training_kernels[name].launches += t.launches;
    }
    const auto t_fit = Clock::now();
    begin += pass_spp;
    add_pixel_estimates(pixel_sum, pass, pass_spp);
    keep_samples(guide_samples, pass);
    const GuideCache sampled_by = guide.header.origin.w > 0 ? guide : GuideCache{};  // what guided the pass
    refine_guide_regions(guide, records);  // where the pass's records crowd (guide_tree.cpp)
    guide_info.records = records.size();
    guide_info.regions_guided = fit_guide_cache(guide, records, &sampled_by);
    if (opt.guide_cache_hook) opt.guide_cache_hook(guide);
    if (const char* e = std::getenv("SPECTRACK_GUIDE_REPORT"); e && std::string(e) == "1") report_guide(int(k));
    guide.header.origin.w = 1.0f;  // the next passes and the render sample the guide
    guide_info.training_passes = int(k) + 1;
    guide_info.seconds_fit += seconds_since(t_fit);
    if (pass.interrupted) {
      interrupted = true;
      break;
    }
  }
  guide.header.inv_cell.w = 0.0f;  // no records in the render
  set_pixel_estimates(guide, pixel_sum, double(std::max<int64_t>(begin, 1)));
  if (!opt.guide_cache_file.empty() && !interrupted) {  // an interrupted training writes nothing
    write_guide_cache_file(opt.guide_cache_file, guide, guide_cache_key());
    guide_info.cache_file = "written";
  }
  finish_guide();
  training.restore();
  crop_to_window(guide_samples, window, settings.full_width);
  if (!schedule.keep) guide_samples = RenderResult{};  // measurements: the render renders every sample
  guide_info.seconds_training = seconds_since(t0);
  guide_info.cpu_seconds_training = double(std::clock() - cpu0) / CLOCKS_PER_SEC;
  return guide_info.seconds_training;
}

}  // namespace spectrack
