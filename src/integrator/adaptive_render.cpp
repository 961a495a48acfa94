// adaptive_render.cpp: an adaptive render's rounds (adaptive.h render_adaptive): the weighted
// film of the rounds' samples, each round rendered as one list of entries (a pixel and the offset
// of its first sample), the pilot's weights, and the film, samples layer and stop reason it ends
// with. The rules that decide a round (weights, lengths, the cap and the aim) are adaptive.cpp's.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <map>
#include <memory>
#include <numeric>
#include <vector>

#include "integrator/adaptive.h"
#include "integrator/film_watch.h"
#include "integrator/noise.h"
#include "util/error.h"

namespace spectrack {
namespace {

// The weighted sums of one window's film: beauty R, G, B, then the film layers' sums (the second
// moments' columns unused: finish() makes them from the pixels' variances).
struct WeightedFilm {
  size_t na = 0, stride = 0;
  int64_t m2 = -1, env = -1;  // columns of moment2.R and (transparent film) environment.R
  std::vector<std::string> channels;
  std::vector<double> w;
  std::vector<AdaptivePixel> px;

  WeightedFilm(const RenderSettings& s) : channels(aov_sum_channels(s.aovs)) {
    na = channels.size();
    stride = 3 + na;
    for (size_t q = 0; q < na; ++q) {
      if (channels[q] == "moment2.R") m2 = int64_t(q);
      if (channels[q] == "environment.R" && (s.aovs & ST_AOV_BIT(ALPHA))) env = int64_t(q);
    }
    if (m2 < 0) throw Error("internal: adaptive sampling without the variance layer");
    w.assign(s.window.pixels() * stride, 0.0);
    px.resize(s.window.pixels());
  }

  // The sums and sums of squares of the whole beauty of round-pixel j of `rr`.
  void beauty_sums(const RenderResult& rr, size_t j, double* s1, double* s2) const {
    for (int c = 0; c < 3; ++c) {
      s1[c] = rr.sum[j * 3 + c] + (env >= 0 ? rr.aov_sum[j * na + size_t(env) + c] : 0.0);
      s2[c] = rr.aov_sum[j * na + size_t(m2) + c];
    }
  }

  // Adds round-pixel j of `rr` (k samples) to window pixel p with weight a.
  void add(const RenderResult& rr, size_t j, uint32_t p, double a, int64_t k) {
    double s1[3], s2[3];
    beauty_sums(rr, j, s1, s2);
    double* o = &w[p * stride];
    const double f = a / double(k);
    for (int c = 0; c < 3; ++c) o[c] += f * rr.sum[j * 3 + c];
    for (size_t q = 0; q < na; ++q) o[3 + q] += f * rr.aov_sum[j * na + q];
    adaptive_add_round(px[p], a, k, s1, s2);
    if (j < rr.pixel_work.size()) px[p].work += rr.pixel_work[j];
  }

  // The film as a render of spp samples (adaptive.h AdaptiveResult::film).
  void finish(RenderResult& f, const RenderSettings& s, int64_t spp) const {
    const size_t npix = px.size();
    const double n = double(spp);
    f.width = s.window.width;
    f.height = s.window.height;
    f.sample_begin = 0;
    f.spp_requested = int(spp);
    f.spp_done = int(spp);
    f.aov_channels = channels;
    f.sum.assign(npix * 3, 0.0);
    f.aov_sum.assign(npix * na, 0.0);
    f.rgb.assign(npix * 3, 0.0f);
    for (size_t p = 0; p < npix; ++p) {
      const AdaptivePixel& x = px[p];
      const double taken = 1.0 - x.B;  // 1 unless the render was stopped
      if (!(taken > 0.0)) continue;
      const double scale = n / taken;
      for (int c = 0; c < 3; ++c) {
        f.sum[p * 3 + c] = w[p * stride + c] * scale;
        f.rgb[p * 3 + c] = float(f.sum[p * 3 + c] / n);
      }
      for (size_t q = 0; q < na; ++q) f.aov_sum[p * na + q] = w[p * stride + 3 + q] * scale;
      for (int c = 0; c < 3; ++c) {  // S2 = n (n - 1) v + S1^2 / n gives film.h's variance v
        const double s1 = f.sum[p * 3 + c] + (env >= 0 ? f.aov_sum[p * na + size_t(env) + c] : 0.0);
        const double v = x.sample_variance(c) * x.V / (taken * taken);
        f.aov_sum[p * na + size_t(m2) + c] = n >= 2 ? n * (n - 1.0) * v + s1 * s1 / n : s1 * s1;
      }
    }
  }
};

// kNoiseFloor times the mean brightness of the pixels whose pilot is noisy (noise.h).
double pilot_floor(const std::vector<AdaptivePixel>& px) {
  double total = 0;
  uint64_t count = 0;
  for (const AdaptivePixel& x : px) {
    const double m = x.brightness(), v = x.sample_variance(0) + x.sample_variance(1) + x.sample_variance(2);
    if (m > 0.0 && v > 0.0) {
      total += m;
      ++count;
    }
  }
  return count ? kNoiseFloor * total / double(count) : 0.0;
}

void add_round_info(RenderResult& f, const RenderResult& rr, bool first) {
  if (first) {
    RenderStats none;
    f = rr;
    f.stats = none;
    f.seconds_render = 0;
  }
  f.stats.add(rr.stats);
  f.seconds_render += rr.seconds_render;
  f.time_limit_reached = f.time_limit_reached || rr.time_limit_reached;
}

// A round's pixels by the samples they take in it, longest first.
using RoundGroups = std::map<int64_t, std::vector<uint32_t>, std::greater<int64_t>>;

// The pilot's weights (adaptive_pilot_weights) from the pilot's render `rr` of every window pixel.
// With guiding the neighbours' pilots are drawn with a guide trained on the pixel's own training
// samples, which are part of its pilot: the weights stay k_0 / spp.
void set_pilot_weights(const RenderResult& rr, const WeightedFilm& film, const RenderSettings& s,
                       const AdaptivePlan& plan, std::vector<double>& wt) {
  std::vector<AdaptivePixel> pilot(film.px.size());
  if (s.guiding || rr.spp_done < 2 || rr.sum.size() != 3 * pilot.size()) return;
  for (size_t j = 0; j < pilot.size(); ++j) {
    double s1[3], s2[3];
    film.beauty_sums(rr, j, s1, s2);
    adaptive_add_round(pilot[j], 1.0, rr.spp_done, s1, s2);
  }
  wt = adaptive_pilot_weights(pilot, s.window.width, s.window.height, plan);
}

// A round's pixels as the entries of one render (Renderer::render_pixels): a pixel taking L
// samples has L / unit entries of `unit` samples, entry i at samples n + i unit .., unit the
// greatest common divisor of the round's lengths; the same samples as a render per length, with
// one drain of the stage loop instead of one per length. Pixel i's entries are first[i] ..
// first[i + 1] - 1. Empty (a render per length) where there is one length, or where the list would
// be longer than `most` entries (the window's pixels: the pilot's film, which had to fit, bounds
// the film of every round).
struct RoundEntries {
  int64_t unit = 0;
  std::vector<uint32_t> pixels, offsets, round_pixels;
  std::vector<size_t> first;
};

RoundEntries round_entries(const RoundGroups& groups, size_t most) {
  RoundEntries e;
  if (groups.size() < 2) return e;
  size_t count = 0;
  for (const auto& [len, pix] : groups) e.unit = std::gcd(e.unit, len);
  for (const auto& [len, pix] : groups) count += size_t(len / e.unit) * pix.size();
  if (count > most) return RoundEntries{};
  for (const auto& [len, pix] : groups)
    for (const uint32_t p : pix) {
      e.first.push_back(e.pixels.size());
      e.round_pixels.push_back(p);
      for (int64_t i = 0; i < len / e.unit; ++i) {
        e.pixels.push_back(p);
        e.offsets.push_back(uint32_t(i * e.unit));
      }
    }
  e.first.push_back(e.pixels.size());
  return e;
}

// The render of entries `rr` as a render of the round's pixels: each pixel's sums are its entries'
// (its work counter, per window pixel, counted once).
RenderResult fold_entries(const RenderResult& rr, const RoundEntries& e, size_t na) {
  RenderResult f;
  const size_t n = e.round_pixels.size();
  f.sum.assign(3 * n, 0.0);
  f.aov_sum.assign(na * n, 0.0);
  if (!rr.pixel_work.empty()) f.pixel_work.resize(n);
  for (size_t i = 0; i < n; ++i) {
    for (size_t j = e.first[i]; j < e.first[i + 1]; ++j) {
      for (int c = 0; c < 3; ++c) f.sum[i * 3 + c] += rr.sum[j * 3 + c];
      for (size_t q = 0; q < na; ++q) f.aov_sum[i * na + q] += rr.aov_sum[j * na + q];
    }
    if (!rr.pixel_work.empty()) f.pixel_work[i] = rr.pixel_work[e.first[i]];
  }
  return f;
}

// Renders one round, starting at sample n: one render of its entries (round_entries), else each
// group one render of its pixels; added with the weights wt (per window pixel; the pilot's set from
// the pilot, n = 0). Returns whether the render was stopped.
bool render_round(Renderer& r, const RoundGroups& groups, std::vector<double>& wt, int64_t n, WeightedFilm& film,
                  const AdaptivePlan& plan, AdaptiveResult& out) {
  static const bool trace = std::getenv("SPECTRACK_TRACE_ADAPTIVE") != nullptr;
  auto traced = [&](const RenderResult& rr, int64_t len, size_t pixels) {
    if (trace)
      std::cerr << fmt::format("round {} (aim {:.2f}, cap {}): {} samples of {} entries from sample {}: {:.3f} s, occupancy {:.2f}, {} iterations\n",
                 out.rounds, out.aim, out.cap, len, pixels, n, rr.seconds_render, rr.stats.occupancy_mean, rr.stats.iterations);
    add_round_info(out.film, rr, out.film.width == 0);
  };
  const RoundEntries e = round_entries(groups, r.settings().window.pixels());
  if (!e.pixels.empty()) {
    const RenderResult rr = r.render_pixels(e.pixels, n, int(e.unit), e.offsets);
    traced(rr, e.unit, e.pixels.size());
    if (rr.spp_done > 0) {
      const RenderResult f = fold_entries(rr, e, film.na);
      for (size_t i = 0; i < e.round_pixels.size(); ++i)
        film.add(f, i, e.round_pixels[i], wt[e.round_pixels[i]], int64_t(e.first[i + 1] - e.first[i]) * rr.spp_done);
    }
    return rr.interrupted;
  }
  for (const auto& [len, pix] : groups) {
    const RenderResult rr = r.render_pixels(pix, n, int(len));
    traced(rr, len, pix.size());
    if (n == 0 && rr.spp_done == int(len)) set_pilot_weights(rr, film, r.settings(), plan, wt);
    if (rr.spp_done > 0)
      for (size_t j = 0; j < pix.size(); ++j) film.add(rr, j, pix[j], wt[pix[j]], rr.spp_done);
    if (rr.interrupted) return true;
  }
  return false;
}

// SPECTRACK_ADAPTIVE_PIXELS=FILE: each pixel's samples, work and unweighted sums, one line each
// (bench/adaptive_oracle.py reads it). The file is opened before the render, so that a path that
// cannot be written fails at once rather than after the whole render.
using PixelTrace = std::unique_ptr<std::FILE, int (*)(std::FILE*)>;

PixelTrace open_pixel_trace() {
  const char* path = std::getenv("SPECTRACK_ADAPTIVE_PIXELS");
  if (!path || !*path) return PixelTrace(nullptr, &std::fclose);
  PixelTrace f(std::fopen(path, "w"), &std::fclose);
  if (!f) throw Error(fmt::format("SPECTRACK_ADAPTIVE_PIXELS: cannot write '{}': {}", path, std::strerror(errno)));
  return f;
}

void write_pixel_trace(std::FILE* f, const std::vector<AdaptivePixel>& px) {
  if (!f) return;
  fmt::print(f, "# pixel n work B V s1R s1G s1B s2R s2G s2B\n");
  for (size_t p = 0; p < px.size(); ++p) {
    const AdaptivePixel& x = px[p];
    fmt::print(f, "{} {} {} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g}\n", p, x.n, x.work, x.B, x.V,
               x.s1[0], x.s1[1], x.s1[2], x.s2[0], x.s2[1], x.s2[2]);
  }
}

// The most samples a pixel took.
int64_t most_samples(const std::vector<AdaptivePixel>& px) {
  int64_t most = 0;
  for (const AdaptivePixel& x : px) most = std::max(most, int64_t(x.n));
  return most;
}

}  // namespace

AdaptiveResult render_adaptive(Renderer& r, const AdaptivePlan& plan,
                               const std::function<void(const AdaptiveResult&)>& after_round) {
  const RenderSettings& s = r.settings();
  if (!s.adaptive) throw Error("internal: an adaptive render with a renderer made without adaptive sampling");
  if (plan.spp < 1 || !(plan.target > 0)) throw Error("internal: an adaptive render needs spp >= 1 and a target");
  const PixelTrace trace = open_pixel_trace();
  WeightedFilm film(s);
  AdaptiveResult out;
  std::vector<uint32_t> active(s.window.pixels());
  std::iota(active.begin(), active.end(), 0u);
  out.floor = plan.floor;
  int64_t n = 0;
  bool stopped = false;
  while (!active.empty() && n < plan.spp && !stopped) {
    const int64_t k = adaptive_round_samples(n, plan);
    const std::vector<double> rho = adaptive_neighbourhood(film.px, s.window.width, s.window.height, out.floor);
    AdaptivePlan round = plan;  // this round's aim: from the drift so far
    if (n > 0) round = adaptive_aim(film.px, rho, out.floor, plan);
    const int64_t cap = n == 0 ? plan.spp : adaptive_cap(film.px, rho, round);
    RoundGroups groups;
    std::vector<double> wt(film.px.size());
    for (const uint32_t p : active) {
      AdaptivePixel& x = film.px[p];
      wt[p] = adaptive_round_weight(x, k, cap, rho[p], round);
      const int64_t len = adaptive_round_length(x, k, cap, rho[p], round);
      groups[len].push_back(p);
      if (wt[p] >= x.B && n > 0) {
        x.predicted = std::sqrt(rho[p] * (x.V + x.B * x.B / double(len)));
        x.decided = x.n;
      }
    }
    out.aim = round.aim;
    out.cap = cap;
    stopped = render_round(r, groups, wt, n, film, plan, out);
    if (n == 0 && plan.floor <= 0) out.floor = pilot_floor(film.px);
    n += k;
    ++out.rounds;
    out.round_end = n;
    if (stopped) out.round_end = most_samples(film.px);  // the round's samples were not all drawn
    if (out.rounds == 1) out.noise_measured = !stopped;  // the pilot
    active.erase(std::remove_if(active.begin(), active.end(), [&](uint32_t p) { return film.px[p].done(); }),
                 active.end());
    if (after_round) {
      film.finish(out.film, s, plan.spp);
      after_round(out);
    }
  }
  RenderResult& f = out.film;
  film.finish(f, s, plan.spp);
  f.interrupted = stopped;
  if (std::all_of(film.px.begin(), film.px.end(), [](const AdaptivePixel& x) { return x.n == 0; }))
    f.spp_done = 0;  // stopped before the pilot's first batch: nothing to write
  out.samples.resize(film.px.size());
  double total = 0;
  for (size_t p = 0; p < film.px.size(); ++p) {
    out.samples[p] = float(film.px[p].n);
    total += double(film.px[p].n);
  }
  out.mean_samples = film.px.empty() ? 0.0 : total / double(film.px.size());
  write_pixel_trace(trace.get(), film.px);
  if (std::getenv("SPECTRACK_TRACE_ADAPTIVE")) {  // the samples the weights waste: 1 / V is a uniform render's n
    double taken = 0, effective = 0;
    for (const AdaptivePixel& x : film.px)
      if (x.V > 0 && adaptive_relative_variance(x, 0.0) > 0) {
        taken += double(x.n);
        effective += 1.0 / x.V;
      }
    std::cerr << fmt::format("samples of the noisy pixels {:.0f}, as effective as {:.0f} equally weighted ({:.3f})\n", taken,
               effective, effective / taken);
  }
  const NoiseEstimate e = estimate_film_noise(f.sum, f.aov_sum, f.aov_channels, plan.spp);
  f.noise_target_reached = !stopped && e.measured && e.error <= plan.target;
  if (!stopped && !f.noise_target_reached)
    out.stop_reason = std::any_of(film.px.begin(), film.px.end(), [&](const AdaptivePixel& x) { return x.n >= plan.spp; })
                          ? "spp"
                          : "pixels-finished";
  return out;
}

MultiDeviceResult render_adaptive_film(const SceneDesc& scene, const RenderOptions& base, const RenderSettings& settings,
                                       const std::string& device) {
  RenderOptions opt = base;
  opt.device = device;
  opt.watch = nullptr;  // a round's film is not the render's: the watch sees the adaptive film
  opt.progress = nullptr;
  Renderer renderer(scene, settings, opt);
  AdaptivePlan plan;
  plan.target = settings.noise_target;
  plan.spp = settings.spp;
  plan.pilot = kNoiseMinSpp;
  const AdaptiveResult a = render_adaptive(renderer, plan, [&](const AdaptiveResult& so_far) {
    if (base.watch && so_far.noise_measured) base.watch->see(so_far.film, nullptr);  // the preview, the noise
    if (base.progress) base.progress(double(so_far.round_end) / double(plan.spp));
  });
  const RenderResult& f = a.film;
  MultiDeviceResult out = device_result(f);
  out.piece = piece_from_result(f, render_identity(settings), "render");
  out.piece.pixel_samples = a.samples;
  out.devices = {renderer.device_name()};
  out.samples_per_device = {std::llround(a.mean_samples)};  // samples per pixel, as a uniform render's: the mean
  out.record_settings(settings);
  out.spp_requested = settings.spp;
  out.piece.interrupted = f.interrupted;
  out.adaptive_rounds = a.rounds;
  out.adaptive_floor = a.floor;
  out.stop_reason = a.stop_reason;
  return out;
}

}  // namespace spectrack
