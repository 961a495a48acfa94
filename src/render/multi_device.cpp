// multi_device.cpp: see multi_device.h. Threads share one mutex for the chunk counter, the
// progress sums and the first error; everything else (renderer, piece, stats) is per device.
#include "render/multi_device.h"

#include <fmt/format.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdlib>
#include <exception>
#include <mutex>
#include <sstream>
#include <thread>

#include "cl/opencl.h"

namespace spectrack {

std::vector<std::string> parse_device_list(const std::string& spec_in) {
  std::string spec = spec_in;
  if (spec.empty())
    if (const char* e = std::getenv("SPECTRACK_DEVICE")) spec = e;
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

MultiDeviceResult render_multi_device(const SceneDesc& scene, const RenderOptions& base,
                                      const std::vector<std::string>& devices, const RenderIdentity& id,
                                      int64_t sample_begin, int spp, int chunk_spp) {
  const size_t n_dev = devices.size();
  if (n_dev == 0) throw Error("internal: no device to render on");
  if (spp < 1) throw Error("internal: empty sample range");
  if (chunk_spp <= 0) chunk_spp = n_dev == 1 ? spp : std::max(1, (spp + int(4 * n_dev) - 1) / int(4 * n_dev));

  MultiDeviceResult out;
  out.devices.assign(n_dev, "");
  out.samples_per_device.assign(n_dev, 0);
  out.spp_requested = spp;
  std::vector<FilmPiece> pieces(n_dev);
  std::vector<RenderStats> stats(n_dev);
  std::vector<double> setup_s(n_dev, 0), build_s(n_dev, 0);
  std::vector<char> from_cache(n_dev, 1);
  std::vector<double> first_pass(n_dev, -1.0);
  std::vector<uint32_t> features(n_dev, 0);

  std::mutex mu;
  int64_t next = sample_begin;
  const int64_t end = sample_begin + spp;
  std::vector<double> in_chunk(n_dev, 0.0);  // samples done of each device's current chunk
  int64_t finished = 0;
  std::exception_ptr error;
  std::atomic<bool> failed{false};
  auto stopped = [&] { return failed.load() || (base.stop && base.stop->load()); };
  auto report = [&] {  // with mu held
    if (!base.progress) return;
    double f = double(finished);
    for (double c : in_chunk) f += c;
    base.progress(std::min(1.0, f / double(spp)));
  };

  auto t0 = std::chrono::steady_clock::now();
  auto work = [&](size_t i) {
    try {
      RenderOptions opt = base;
      opt.device = devices[i];
      int64_t chunk_len = 0;
      opt.progress = [&, i](double f) {
        std::lock_guard<std::mutex> lock(mu);
        in_chunk[i] = f * double(chunk_len);
        report();
      };
      Renderer r(scene, opt);
      {
        std::lock_guard<std::mutex> lock(mu);
        out.devices[i] = r.device_name();
      }
      pieces[i].source = fmt::format("device {} ({})", devices[i].empty() ? "default" : devices[i], r.device_name());
      pieces[i].id = id;
      while (!stopped()) {
        int64_t begin;
        {
          std::lock_guard<std::mutex> lock(mu);
          if (next >= end) break;
          begin = next;
          chunk_len = std::min<int64_t>(chunk_spp, end - next);
          next += chunk_len;
        }
        RenderResult res = r.render(begin, int(chunk_len));
        FilmPiece& p = pieces[i];
        if (p.sum.empty()) {
          p.x0 = res.x0, p.y0 = res.y0, p.width = res.width, p.height = res.height;
          p.sum.assign(res.sum.size(), 0.0);
          setup_s[i] = res.seconds_setup;
          build_s[i] = res.seconds_build;
          from_cache[i] = res.kernels_from_cache;
          first_pass[i] = res.seconds_first_pass;
          features[i] = res.features;
        }
        for (size_t k = 0; k < res.sum.size(); ++k) p.sum[k] += res.sum[k];
        if (res.spp_done > 0) p.ranges.push_back({begin, begin + res.spp_done});
        p.ranges = join_ranges(p.ranges);
        p.interrupted |= res.interrupted;
        stats[i].add(res.stats);
        std::lock_guard<std::mutex> lock(mu);
        out.samples_per_device[i] += res.spp_done;
        finished += res.spp_done;
        in_chunk[i] = 0;
        report();
        if (res.interrupted) break;
      }
    } catch (...) {
      std::lock_guard<std::mutex> lock(mu);
      if (!error) {
        try {
          throw;
        } catch (const std::exception& e) {
          error = std::make_exception_ptr(Error(
              n_dev == 1 ? std::string(e.what())
                         : fmt::format("device {} of --device list: {}", devices[i].empty() ? "default" : devices[i],
                                       e.what())));
        } catch (...) {
          error = std::current_exception();
        }
      }
      failed.store(true);
    }
  };
  if (n_dev == 1) {
    work(0);
  } else {
    std::vector<std::thread> threads;
    for (size_t i = 0; i < n_dev; ++i) threads.emplace_back(work, i);
    for (auto& t : threads) t.join();
  }
  if (error) std::rethrow_exception(error);
  out.seconds_render = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  std::vector<FilmPiece> with_samples;
  bool interrupted = base.stop && base.stop->load();
  for (size_t i = 0; i < n_dev; ++i) {
    interrupted |= pieces[i].interrupted;
    if (pieces[i].samples() > 0) with_samples.push_back(pieces[i]);
    out.stats.add(stats[i]);
    out.seconds_setup = std::max(out.seconds_setup, setup_s[i]);
    out.seconds_build = std::max(out.seconds_build, build_s[i]);
    out.kernels_from_cache = out.kernels_from_cache && from_cache[i];
    if (first_pass[i] >= 0) {
      out.seconds_first_pass = out.seconds_first_pass > 0 ? std::min(out.seconds_first_pass, first_pass[i]) : first_pass[i];
      out.features = features[i];
    }
  }
  out.tracker = base.tracker >= 0 ? base.tracker : scene.render.tracker;
  out.scheme = base.scheme >= 0 ? base.scheme : scene.render.scheme;
  out.seed = base.seed >= 0 ? uint32_t(base.seed) : scene.render.seed;
  if (with_samples.empty()) {  // stopped before any sample finished
    FilmPiece& p = out.piece;
    p = pieces[0];
    p.source = "render";
    if (p.sum.empty()) {
      auto [x0, x1, y0, y1] = base.pixel_bounds;
      if (x1 < 0) x0 = 0, x1 = scene.film.width, y0 = 0, y1 = scene.film.height;
      p.x0 = x0, p.y0 = y0, p.width = x1 - x0, p.height = y1 - y0;
      p.sum.assign(size_t(p.width) * p.height * 3, 0.0);
    }
    p.ranges.clear();
  } else {
    out.piece = with_samples.size() == 1 ? with_samples[0] : merge_pieces(with_samples);
  }
  out.piece.source = "render";
  out.piece.interrupted = interrupted || out.piece.samples() < spp;
  return out;
}

}  // namespace spectrack
