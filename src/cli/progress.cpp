// progress.cpp: see progress.h. The callback runs on the render's thread(s) (several devices call
// it under the multi-device lock), so its state is behind a shared pointer and the clock is read
// on each call; the rate is measured from the first call (the stage loop's start, so kernel
// builds do not count against it). A failed write to stderr (its reader gone) ends the output.
#include "cli/progress.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <deque>
#include <memory>
#include <string>

namespace spectrack {
namespace {

using Clock = std::chrono::steady_clock;

std::string duration_str(double s) {
  if (!std::isfinite(s) || s < 0) return "?";
  const long long t = (long long)std::llround(s);
  if (t < 60) return fmt::format("{} s", t);
  if (t < 3600) return fmt::format("{}:{:02}", t / 60, t % 60);
  return fmt::format("{}:{:02}:{:02}", t / 3600, (t / 60) % 60, t % 60);
}

std::string samples_str(double v) { return v == std::floor(v) || v >= 100 ? fmt::format("{:.0f}", v) : fmt::format("{:.1f}", v); }

struct State {
  bool started = false, finished = false;
  Clock::time_point t0, last;
  std::deque<std::pair<Clock::time_point, double>> window;  // (time, samples) of recent calls
};

// The rate over the last ~15 s of calls (the first launches, which may compile kernels, then
// stop weighing on the estimate), from the first call while the render is younger than that.
double recent_rate(State& st, Clock::time_point now, double got) {
  st.window.emplace_back(now, got);
  while (st.window.size() > 2 && std::chrono::duration<double>(now - st.window[1].first).count() > 15.0)
    st.window.pop_front();
  const double dt = std::chrono::duration<double>(now - st.window.front().first).count();
  return dt > 0 ? (got - st.window.front().second) / dt : 0.0;
}

}  // namespace

std::function<void(double)> progress_reporter(bool quiet, bool tty, double samples, double log_interval_s,
                                              std::function<std::string()> note) {
  auto st = std::make_shared<State>();
  return [=](double f) {
    if (quiet || st->finished) return;
    f = std::clamp(f, 0.0, 1.0);
    const Clock::time_point now = Clock::now();
    const bool first = !st->started;
    if (first) st->started = true, st->t0 = now;
    if (first) st->window.emplace_back(now, 0.0);
    const double since_last = std::chrono::duration<double>(now - st->last).count();
    const bool done = f >= 1.0;
    const double interval = tty ? 0.25 : log_interval_s;
    if (!first && !done && since_last < interval) return;
    st->last = now;
    st->finished = done;
    const double elapsed = std::chrono::duration<double>(now - st->t0).count();
    const double got = f * samples;
    const double rate = done ? (elapsed > 0 ? got / elapsed : 0.0) : recent_rate(*st, now, got);
    const std::string rate_s = rate > 0 ? fmt::format("{:.3g} spp/s", rate) : std::string("- spp/s");
    const std::string eta = done ? fmt::format("took {}", duration_str(elapsed))
                                 : rate > 0 ? "ETA " + duration_str((samples - got) / rate) : std::string("ETA ?");
    const int pct = int(std::floor(f * 100.0));
    const std::string extra = note ? note() : std::string();
    const std::string tail = extra.empty() ? eta : eta + ", " + extra;
    int n = 0;
    if (tty) {
      const int bar = int(f * 30.0);
      n = std::fprintf(stderr, "\r[%-30s] %3d%%  %s/%s spp  %s  %s\033[K", std::string(size_t(bar), '#').c_str(), pct,
                       samples_str(got).c_str(), samples_str(samples).c_str(), rate_s.c_str(), tail.c_str());
    } else {
      n = std::fprintf(stderr, "progress: %d%% (%s/%s spp, %s, %s)\n", pct, samples_str(got).c_str(),
                       samples_str(samples).c_str(), rate_s.c_str(), tail.c_str());
    }
    // a reader of stderr that went away (EPIPE; SIGPIPE is ignored) stops the progress, not the render
    if (std::fflush(stderr) != 0 || n < 0) st->finished = true;
  };
}

}  // namespace spectrack
