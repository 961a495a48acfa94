// render_py.cpp: Scene.render of the Python module: the library's render_call (src/api) on a
// worker thread while the calling thread, holding the GIL only briefly every 50 ms, runs Python's
// signal handlers (PyErr_CheckSignals) and the progress callback.
//
// Design: the GIL is released for the whole render, so other Python threads run. A
// KeyboardInterrupt (Ctrl-C) or an exception from the progress callback sets the renderer's stop
// flag: its stage loop ends at the next iteration (well under a second) with the finished batches
// on the film, as `spectrack render` does on SIGINT; the exception is then raised again with the
// image of the finished samples as its `image` attribute. The settings are the command line's:
// RenderOptions filled from the keyword arguments and resolved by the same resolve_settings.
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <atomic>
#include <chrono>
#include <exception>
#include <future>
#include <optional>

#include "api/render_call.h"
#include "api/render_stats.h"
#include "cli/checks.h"
#include "image_py.h"
#include "integrator/option_table.h"
#include "render_py.h"
#include "warnings_py.h"

namespace py = pybind11;

namespace spectrack {
namespace python {
namespace {

int named(const std::optional<std::string>& v, int (*from_name)(const std::string&), std::string (*names)(),
          const char* what) {
  const int k = from_name(*v);
  if (k < 0) throw py::value_error(fmt::format("{}={}: unknown {} (one of: {})", what, *v, what, names()));
  return k;
}

// The film layers: the scene's film.aovs, the names in `aovs`, and alpha when `alpha` or `aovs`
// says (else film.alpha, else off: an array holds the whole beauty); "alpha" in `aovs` with
// alpha=False is refused, as the command line refuses --aov alpha with --no-alpha.
uint32_t film_layers(const SceneDesc& scene, const std::vector<std::string>& aovs, std::optional<bool> alpha) {
  uint32_t bits = scene.film.aovs & ~uint32_t(ST_AOV_BIT(ALPHA));
  bool alpha_listed = false;
  for (const std::string& n : aovs) {
    const int k = aov_from_name(n);
    if (k < 0) throw py::value_error(fmt::format("aovs: unknown layer '{}' (one of: {})", n, aov_names()));
    if (k == ST_AOV_INDEX_ALPHA) alpha_listed = true;
    else bits |= 1u << k;
  }
  if (alpha_listed && alpha == false) throw py::value_error("aovs lists alpha, which alpha=False turns off");
  if (alpha_listed || alpha.value_or(scene.film.alpha.value_or(false))) bits |= uint32_t(ST_AOV_BIT(ALPHA));
  return bits;
}

RenderOptions options_of(const SceneDesc& scene, const RenderArgs& a) {
  RenderOptions opt;
  opt.quiet = !a.verbose;
  if (a.spp) {
    if (*a.spp < 1 || *a.spp > (1 << 24)) throw py::value_error(fmt::format("spp={}: 1 to 2^24", *a.spp));
    opt.spp = a.spp;
  }
  if (a.seed) {
    if (*a.seed < 0 || *a.seed > 4294967295LL) throw py::value_error(fmt::format("seed={}: 0 to 2^32-1", *a.seed));
    opt.seed = a.seed;
  }
  if (a.spp_range) {
    if (a.spp) throw py::value_error("spp and spp_range: give one");
    const auto [b, e] = *a.spp_range;
    if (b < 0 || e <= b || e - b > (1 << 24))
      throw py::value_error(fmt::format("spp_range=({}, {}): need 0 <= begin < end, at most 2^24 samples", b, e));
    opt.sample_begin = b;
    opt.spp = int(e - b);
    opt.sample_range = true;
  }
  if (a.time_limit) {  // --time-limit's range (a longer one overflows the deadline); NaN is refused
    const OptionCheck& range = option_row("time_limit").check;
    if (!(*a.time_limit >= range.lo && *a.time_limit <= range.hi))
      throw py::value_error(fmt::format("time_limit={}: seconds, from {:g} to {:g} (--time-limit's range)", *a.time_limit,
                                        range.lo, range.hi));
  }
  if (a.pixel_bounds) opt.pixel_bounds = *a.pixel_bounds;
  if (a.tracker) opt.tracker = named(a.tracker, tracker_from_name, tracker_names, "tracker");
  if (a.scheme) opt.scheme = named(a.scheme, scheme_from_name, scheme_names, "scheme");
  if (a.guiding) opt.guiding = named(a.guiding, guiding_from_name, guiding_names, "guiding");
  opt.guide_cache_file = a.guide_cache;
  opt.guide_splitting = a.guide_splitting;
  opt.scene_json = a.json_text;  // resolve_settings refuses a guide cache without guiding
  opt.aovs = film_layers(scene, a.aovs, a.alpha);
  // the command line's refusals of what would be ignored (ValueError, as the CLI's exit 2)
  check_tracker_scheme(scene, opt, a.scheme.value_or(""), a.tracker.value_or(""));
  check_wavelength_sampling(scene, opt, "");  // the scene's field in rgb mode: a warning
  const OptionCheck& chunk = option_row("chunk_spp").check;  // --chunk-spp's range; 0: by the device count
  if (a.chunk_spp != 0 && !(a.chunk_spp >= chunk.lo && a.chunk_spp <= chunk.hi))
    throw py::value_error(fmt::format("chunk_spp={}: 0 (by the device count) or {:.0f} to {:.0f} (--chunk-spp's range)",
                                      a.chunk_spp, chunk.lo, chunk.hi));
  check_chunk_spp(a.chunk_spp > 0 ? std::optional<int>(a.chunk_spp) : std::nullopt, parse_device_list(a.device),
                  a.device);
  return opt;
}

// Waits for the worker, running signal handlers and the progress callback every 50 ms with the
// GIL held; on an exception from either, sets `stop` and returns it (the worker still finishes).
std::optional<py::error_already_set> watch(std::future<void>& done, std::atomic<bool>& stop,
                                           const std::atomic<double>& fraction, const py::object& progress) {
  std::optional<py::error_already_set> pending;
  double shown = -1;
  py::gil_scoped_release unlocked;
  while (done.wait_for(std::chrono::milliseconds(50)) != std::future_status::ready) {
    if (pending) continue;
    py::gil_scoped_acquire locked;
    flush_warnings();  // the pack's and the devices' warnings while the render runs
    try {
      if (PyErr_CheckSignals() != 0) throw py::error_already_set();
      const double f = fraction.load();
      if (!progress.is_none() && f != shown) progress(f), shown = f;
    } catch (py::error_already_set& e) {
      pending.emplace(std::move(e));
      stop.store(true);
    }
  }
  return pending;
}

}  // namespace

Image render(const SceneDesc& scene, const RenderArgs& args) {
  RenderOptions opt = options_of(scene, args);
  std::atomic<bool> stop{false};
  std::atomic<double> fraction{0};
  opt.stop = &stop;
  opt.progress = [&fraction](double f) { fraction.store(f); };
  const double time_limit = args.time_limit.value_or(scene.render.time_limit);  // as the command line: 0 none
  if (time_limit > 0)
    opt.deadline = std::chrono::steady_clock::now() + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                                          std::chrono::duration<double>(time_limit));
  const auto t0 = std::chrono::steady_clock::now();
  MultiDeviceResult r;
  std::exception_ptr failure;
  std::promise<void> finished;
  std::future<void> done = finished.get_future();
  std::thread worker([&] {
    try {
      r = render_call(scene, opt, args.device, args.chunk_spp, args.json_text);
    } catch (...) {
      failure = std::current_exception();
    }
    finished.set_value();
  });
  std::optional<py::error_already_set> pending = watch(done, stop, fraction, args.progress);
  worker.join();
  if (failure) std::rethrow_exception(failure);
  if (!pending && r.piece.samples() == 0 && r.time_limit_reached) {
    PyErr_SetString(PyExc_TimeoutError, fmt::format("{}: the time limit of {} s came before any sample finished",
                                                    scene.path, time_limit).c_str());
    throw py::error_already_set();
  }
  Image im;
  im.piece = r.piece;
  im.counters = r.stats;
  im.spp_or_pixel_range = args.spp_range.has_value() || args.pixel_bounds.has_value();
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  im.meta = render_metadata(r, scene.path, time_limit);  // the command line's (api/render_stats.h)
  im.stats = render_stats_json(r, seconds, 0.0, 1, im.meta);
  if (args.verbose) {  // the command line's summary, on Python's stderr
    const std::string noise = im.stats.contains("noise_error") && im.stats["noise_error"].is_number()
                                  ? fmt::format(", noise {:.3g}%", 100.0 * im.stats["noise_error"].get<double>())
                                  : std::string();
    py::module_::import("sys").attr("stderr").attr("write")(fmt::format(
        "spectrack: {} on {}: {} spp of {}x{} pixels in {:.3g} s render{}{}\n", scene.path, fmt::join(r.devices, ", "),
        r.piece.samples(), r.piece.width, r.piece.height, r.seconds_render, noise, r.piece.interrupted ? ", interrupted" : ""));
  }
  // the image rides on an exception of the progress callback, the last call's included
  auto with_image = [&](py::error_already_set& e) {
    py::object value = e.value();
    if (value && PyObject_HasAttrString(value.ptr(), "__dict__")) value.attr("image") = py::cast(im);
  };
  if (pending) {
    with_image(*pending);
    throw std::move(*pending);
  }
  if (!args.progress.is_none()) {
    try {
      args.progress(1.0);
    } catch (py::error_already_set& e) {
      with_image(e);
      throw;
    }
  }
  return im;
}

}  // namespace python
}  // namespace spectrack
