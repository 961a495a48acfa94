// progress.h: the render's progress on stderr (progress.cpp).
#pragma once
#include <functional>

namespace spectrack {

// A progress callback for RenderOptions::progress, fed the fraction of this process's `samples`
// done (smooth within batches: integrator/renderer.cpp counts finished paths). On a terminal: one
// redrawn line, at most about 4 times a second; otherwise a line "progress: N% (done/total spp,
// R spp/s, ETA T)" at 0%, every `log_interval_s` seconds and at 100%. Each line shows the samples
// done, the rate since the first call and the time left at that rate. Nothing when `quiet`, and
// nothing more once a write to stderr failed (a closed pipe: the render goes on).
std::function<void(double)> progress_reporter(bool quiet, bool tty, double samples, double log_interval_s = 5.0);

}  // namespace spectrack
