// run_control.h: how a command ends early: signals and the time limit.
//
// Design: install_signal_handlers runs before anything slow: from the executable's preinit array
// (before the shared libraries' initialisers) and again first thing in main. SIGPIPE and
// SIGXFSZ are ignored, so a reader of stderr that goes away or a file-size limit becomes a failed
// write (EPIPE, EFBIG) that the writer handles, never a death by signal. SIGINT and SIGTERM: while
// a stage loop runs, the first one asks it to stop (stop_flag: the finished samples are written,
// exit 130); in every other phase (start-up, scene loading, set-up, merge) and at a second signal
// the handler removes the temporary output files and ends the process at once with 130.
//
// The time limit is a deadline counted from the command's start (with --frames, from each
// frame's start). A watchdog thread (DeadlineWatch) ends the process with kExitTimeLimit at the
// deadline when no stage loop has started by then, whatever it is doing (a kernel build, reading a
// large map): there is no sample to write, and the message names the phase (set_phase, util/phase.h). Once a
// stage loop runs, the renderer stops at its next iteration after the deadline.
#pragma once
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <string>
#include <thread>

#include "util/error.h"
#include "util/phase.h"

namespace spectrack {

constexpr int kExitInterrupted = 130;  // SIGINT, SIGTERM
constexpr int kExitTimeLimit = 3;      // the time limit came before any sample finished: nothing written

void install_signal_handlers();
// When the program's own code started (the preinit array: after the dynamic loader, before the
// shared libraries' initialisers); the time limit counts from here.
std::chrono::steady_clock::time_point command_start();
std::atomic<bool>* stop_flag();          // set by the first SIGINT/SIGTERM while a stage loop runs
std::atomic<bool>* loop_started_flag();  // set by the renderer when its stage loop starts

// The message of a time limit reached before any sample finished ("<what>" is "" or "frame N: ").
std::string time_limit_message(const std::string& what, double limit_s, const char* phase);

// A render that the time limit ended before any sample finished: nothing is written, and the
// command exits with kExitTimeLimit.
struct TimeLimitError : Error {
  using Error::Error;
};

class DeadlineWatch {
 public:
  DeadlineWatch() = default;
  ~DeadlineWatch() { disarm(); }
  DeadlineWatch(const DeadlineWatch&) = delete;
  DeadlineWatch& operator=(const DeadlineWatch&) = delete;
  // Until disarm: at `deadline`, unless a stage loop has started, print time_limit_message and
  // end the process with kExitTimeLimit (temporary output files removed).
  void arm(std::chrono::steady_clock::time_point deadline, double limit_s);
  void disarm();
  // What the messages start with: "" or "frame N: ".
  void set_context(const std::string& what);
  std::string context();

 private:
  void watch();
  std::thread thread_;
  std::mutex mu_;
  std::condition_variable cv_;
  bool armed_ = false;
  std::chrono::steady_clock::time_point deadline_;
  double limit_s_ = 0;
  std::string what_;
};

// The command's watch (one per process).
DeadlineWatch& deadline_watch();

}  // namespace spectrack
