// multi_device.cpp: see multi_device.h. Threads share one mutex for the chunk counter, the
// progress sums and the first error; everything else (renderer, piece, stats) is per device
// (MultiDeviceRun::PerDevice).
#include "integrator/multi_device.h"
#include "integrator/adaptive.h"
#include "integrator/noise.h"

#include <fmt/format.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <mutex>
#include <sstream>
#include <thread>

#include "device/opencl.h"

namespace spectrack {

std::vector<std::string> parse_device_list(const std::string& spec_in) {
  std::string spec = spec_in;
  // one device from SPECTRACK_DEVICE stays "": select_device reads it and names it in its messages
  if (const char* e = std::getenv("SPECTRACK_DEVICE"); spec.empty() && e && (std::string(e) == "all" || std::strchr(e, ',')))
    spec = e;
  if (spec == "all") {
    std::vector<std::string> out;
    for (auto& d : enumerate_devices()) out.push_back(fmt::format("{}:{}", d.platform_index, d.device_index));
    if (out.empty())
      throw Error("--device all: no OpenCL device found (install pocl-opencl-icd or a GPU driver)");
    return out;
  }
  if (spec.find(',') == std::string::npos) return {spec};
  std::vector<std::string> out;
  std::stringstream ss(spec);
  std::string item;
  while (std::getline(ss, item, ',')) {
    if (item.empty()) throw Error(fmt::format("--device {}: empty device in the list", spec));
    out.push_back(item);
  }
  if (spec.back() == ',') throw Error(fmt::format("--device {}: empty device in the list", spec));
  return out;
}

namespace {

// One multi-device render: the shared chunk counter and progress (under mu), and per device its
// film piece and statistics.
class MultiDeviceRun {
 public:
  MultiDeviceRun(const SceneDesc& scene, const RenderOptions& base, const RenderSettings& settings,
                 const std::vector<std::string>& devices, int64_t sample_begin, int spp, int chunk_spp)
      : scene_(scene), base_(base), settings_(settings), devices_(devices), id_(render_identity(settings)),
        n_dev_(devices.size()), next_(sample_begin), end_(sample_begin + spp), spp_(spp), chunk_spp_(chunk_spp),
        dev_(n_dev_), in_chunk_(n_dev_, 0.0) {}

  void run() {
    if (n_dev_ == 1) {
      work(0);
    } else {
      std::vector<std::thread> threads;
      for (size_t i = 0; i < n_dev_; ++i) threads.emplace_back([this, i] { work(i); });
      for (auto& t : threads) t.join();
    }
    if (error_) std::rethrow_exception(error_);
  }
  MultiDeviceResult combine() const;

 private:
  struct PerDevice {
    std::string name;
    FilmPiece piece;
    int64_t samples = 0;
    bool started = false;  // a chunk came back: `run` holds its device_result
    MultiDeviceResult run;  // seconds_render and stats summed over its chunks, the flags or-ed
  };
  bool stopped() const {
    return failed_.load() || (base_.stop && base_.stop->load()) ||
           (base_.deadline && std::chrono::steady_clock::now() >= *base_.deadline);
  }
  void report() const {  // with mu_ held
    if (!base_.progress) return;
    double f = double(finished_);
    for (double c : in_chunk_) f += c;
    base_.progress(std::min(1.0, f / double(spp_)));
  }
  bool next_chunk(int64_t* begin, int64_t* len) {
    std::lock_guard<std::mutex> lock(mu_);
    if (next_ >= end_) return false;
    *begin = next_;
    // a chunk holds all of the guide's training samples or none (settings.h guide_part_boundary)
    *len = std::min<int64_t>(guide_part_boundary(settings_, next_ + chunk_spp_), end_) - next_;
    next_ += *len;
    return true;
  }
  std::string device_label(size_t i) const { return devices_[i].empty() ? "default" : devices_[i]; }
  void add_chunk(size_t i, int64_t begin, const RenderResult& res);
  void work(size_t i);
  void fail(size_t i);

  const SceneDesc& scene_;
  const RenderOptions& base_;
  const RenderSettings& settings_;
  const std::vector<std::string>& devices_;
  const RenderIdentity id_;
  const size_t n_dev_;
  std::mutex mu_;
  int64_t next_, end_;
  const int spp_, chunk_spp_;
  std::vector<PerDevice> dev_;
  std::vector<double> in_chunk_;  // samples done of each device's current chunk
  int64_t finished_ = 0;
  std::exception_ptr error_;
  std::atomic<bool> failed_{false};
};

void MultiDeviceRun::add_chunk(size_t i, int64_t begin, const RenderResult& res) {
  PerDevice& d = dev_[i];
  FilmPiece& p = d.piece;
  if (p.sum.empty()) {
    p.x0 = res.x0, p.y0 = res.y0, p.width = res.width, p.height = res.height;
    p.sum.assign(res.sum.size(), 0.0);
    p.aov_sum.assign(res.aov_sum.size(), 0.0);
  }
  if (!d.started) {
    d.run = device_result(res);
    d.started = true;
  } else {
    d.run.seconds_render += res.seconds_render;
    d.run.cpu_seconds_render += res.cpu_seconds_render;
    d.run.stats.add(res.stats);
    d.run.time_limit_reached |= res.time_limit_reached;
    d.run.noise_target_reached |= res.noise_target_reached;
  }
  for (size_t k = 0; k < res.sum.size(); ++k) p.sum[k] += res.sum[k];
  for (size_t k = 0; k < res.aov_sum.size(); ++k) p.aov_sum[k] += res.aov_sum[k];
  if (res.spp_done > 0) p.ranges.push_back({begin, begin + res.spp_done});
  p.ranges = join_ranges(p.ranges);
  p.interrupted |= res.interrupted;
  std::lock_guard<std::mutex> lock(mu_);
  d.samples += res.spp_done;
  finished_ += res.spp_done;
  in_chunk_[i] = 0;
  report();
}

void MultiDeviceRun::work(size_t i) {
  try {
    RenderOptions opt = base_;
    opt.device = devices_[i];
    int64_t chunk_len = 0;
    opt.progress = [&, i](double f) {
      std::lock_guard<std::mutex> lock(mu_);
      in_chunk_[i] = f * double(chunk_len);
      report();
    };
    Renderer r(scene_, settings_, opt);
    {
      std::lock_guard<std::mutex> lock(mu_);
      dev_[i].name = r.device_name();
    }
    dev_[i].piece.source = fmt::format("device {} ({})", device_label(i), r.device_name());
    dev_[i].piece.id = id_;
    int64_t begin = 0;
    while (!stopped() && next_chunk(&begin, &chunk_len)) {
      RenderResult res = r.render(begin, int(chunk_len));
      add_chunk(i, begin, res);
      if (res.interrupted) break;
    }
  } catch (...) {
    fail(i);
  }
}

// Keeps the first error (naming the device when there are several) and stops the others.
void MultiDeviceRun::fail(size_t i) {
  std::lock_guard<std::mutex> lock(mu_);
  if (!error_) {
    try {
      throw;
    } catch (const std::exception& e) {
      error_ = std::make_exception_ptr(Error(n_dev_ == 1 ? std::string(e.what())
                                                         : fmt::format("device {} of --device list: {}", device_label(i), e.what())));
    } catch (...) {
      error_ = std::current_exception();
    }
  }
  failed_.store(true);
}

MultiDeviceResult MultiDeviceRun::combine() const {
  MultiDeviceResult out;
  out.spp_requested = spp_;
  std::vector<FilmPiece> with_samples;
  bool interrupted = (base_.stop && base_.stop->load()) ||
                     (base_.deadline && std::chrono::steady_clock::now() >= *base_.deadline);
  for (const PerDevice& d : dev_) {
    out.devices.push_back(d.name);
    out.samples_per_device.push_back(d.samples);
    interrupted |= d.piece.interrupted;
    if (d.piece.samples() > 0) with_samples.push_back(d.piece);
    if (!d.started) continue;
    const MultiDeviceResult& r = d.run;
    out.time_limit_reached |= r.time_limit_reached;
    out.noise_target_reached |= r.noise_target_reached;
    out.stats.add(r.stats);
    out.seconds_setup = std::max(out.seconds_setup, r.seconds_setup);
    out.seconds_build = std::max(out.seconds_build, r.seconds_build);
    out.seconds_render = std::max(out.seconds_render, r.seconds_render);
    out.cpu_seconds_render = std::max(out.cpu_seconds_render, r.cpu_seconds_render);
    out.kernels_from_cache = out.kernels_from_cache && r.kernels_from_cache;
    out.seconds_first_pass = out.seconds_first_pass > 0 ? std::min(out.seconds_first_pass, r.seconds_first_pass) : r.seconds_first_pass;
    static_cast<RunChoices&>(out) = static_cast<const RunChoices&>(r);
  }
  out.record_settings(settings_);
  if (with_samples.empty())  // stopped before any sample finished
    out.piece = empty_piece(id_, settings_.window, "render");
  else
    out.piece = with_samples.size() == 1 ? with_samples[0] : merge_pieces(with_samples);
  out.piece.source = "render";
  // a stop or the deadline that came once every sample had finished (a progress callback that
  // raised at its last call) cut nothing short: the image is the whole render
  interrupted = interrupted && out.piece.samples() < spp_;
  // a render that ends at the spp with the target met (a film of one batch is never looked at
  // before its last sample) reached it; below kNoiseMinSpp the variance decides nothing, as for the watch
  if (settings_.noise_target > 0 && !out.noise_target_reached && !interrupted && out.piece.samples() >= kNoiseMinSpp &&
      (settings_.aovs & ST_AOV_BIT(VARIANCE)))
    out.noise_target_reached = estimate_film_noise(out.piece.sum, out.piece.aov_sum, aov_sum_channels(out.piece.id.aovs),
                                                   out.piece.samples()).error <= settings_.noise_target;
  out.piece.interrupted = interrupted || (out.piece.samples() < spp_ && !out.noise_target_reached);
  if (settings_.noise_target > 0 && !out.noise_target_reached && !out.piece.interrupted) out.stop_reason = "spp";
  if (base_.deadline && std::chrono::steady_clock::now() >= *base_.deadline && out.piece.samples() < spp_)
    out.time_limit_reached = true;  // also when the deadline fell between two chunks
  return out;
}

}  // namespace

MultiDeviceResult device_result(const RenderResult& res) {
  MultiDeviceResult out;
  static_cast<RunChoices&>(out) = static_cast<const RunChoices&>(res);
  out.stats = res.stats;
  out.seconds_setup = res.seconds_setup;
  out.seconds_build = res.seconds_build;
  out.seconds_render = res.seconds_render;
  out.cpu_seconds_render = res.cpu_seconds_render;
  out.kernels_from_cache = res.kernels_from_cache;
  out.seconds_first_pass = res.seconds_first_pass;
  out.time_limit_reached = res.time_limit_reached;
  out.noise_target_reached = res.noise_target_reached;
  return out;
}

MultiDeviceResult render_multi_device(const SceneDesc& scene, const RenderOptions& base, const RenderSettings& settings,
                                      const std::vector<std::string>& devices, int64_t sample_begin, int spp,
                                      int chunk_spp) {
  const size_t n_dev = devices.size();
  if (n_dev == 0) throw Error("internal: no device to render on");
  if (spp < 1) throw Error("internal: empty sample range");
  if (settings.noise_target > 0 && n_dev > 1)  // the watch looks at one device's film
    throw UsageError("a noise target (render.noise_target) stops one device's render at its noise: it does not work "
                     "with several devices");
  if (settings.adaptive) {
    if (n_dev > 1 || sample_begin != 0 || spp != settings.spp)
      throw UsageError("adaptive sampling renders on one device, over the whole sample range");
    return render_adaptive_film(scene, base, settings, devices[0]);
  }
  if (chunk_spp <= 0) chunk_spp = n_dev == 1 ? spp : std::max(1, (spp + int(4 * n_dev) - 1) / int(4 * n_dev));
  MultiDeviceRun run(scene, base, settings, devices, sample_begin, spp, chunk_spp);
  run.run();
  return run.combine();
}

}  // namespace spectrack
