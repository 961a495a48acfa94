// run_control.cpp: see run_control.h.
#include "cli/run_control.h"

#include <fmt/format.h>
#include <unistd.h>

#include <csignal>
#include <cstring>

#include "util/output_file.h"

namespace spectrack {
namespace {

std::atomic<bool> g_stop{false};
std::atomic<bool> g_loop_started{false};

// Only async-signal-safe calls here (atomics, unlink, write, _exit).
extern "C" void on_stop_signal(int) {
  if (!g_loop_started.load() || g_stop.load()) {
    remove_temporary_outputs();
    static const char msg[] = "\nspectrack: interrupted: stopping at once, without writing\n";
    ssize_t ignored = ::write(2, msg, sizeof(msg) - 1);
    (void)ignored;
    ::_exit(kExitInterrupted);
  }
  g_stop.store(true);
}

void write_all(int fd, const std::string& s) {
  size_t done = 0;
  while (done < s.size()) {
    const ssize_t n = ::write(fd, s.data() + done, s.size() - done);
    if (n <= 0) return;  // stderr gone: the exit code still tells
    done += size_t(n);
  }
}

}  // namespace

void install_signal_handlers() {
  struct sigaction sa;
  std::memset(&sa, 0, sizeof sa);
  sa.sa_handler = on_stop_signal;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = SA_RESTART;
  ::sigaction(SIGINT, &sa, nullptr);
  ::sigaction(SIGTERM, &sa, nullptr);
  std::signal(SIGPIPE, SIG_IGN);
  std::signal(SIGXFSZ, SIG_IGN);
}

// The executable's .preinit_array runs before the initialisers of every shared library (OpenVDB,
// OpenImageIO, TBB, ...), which take a noticeable time at start-up: the handlers are in place
// from then on, and main installs them again in case a platform skips the array.
static std::chrono::steady_clock::time_point g_start;  // set by spectrack_preinit

extern "C" void spectrack_preinit(int, char**, char**) {
  g_start = std::chrono::steady_clock::now();
  install_signal_handlers();
}
__attribute__((section(".preinit_array"), used)) void (*const spectrack_preinit_entry)(int, char**, char**) =
    spectrack_preinit;

std::chrono::steady_clock::time_point command_start() {
  return g_start == std::chrono::steady_clock::time_point{} ? std::chrono::steady_clock::now() : g_start;
}

std::atomic<bool>* stop_flag() { return &g_stop; }
std::atomic<bool>* loop_started_flag() { return &g_loop_started; }

std::string time_limit_message(const std::string& what, double limit_s, const char* phase) {
  return fmt::format("{}time limit of {:g} s reached during {}; no sample finished; nothing written", what, limit_s,
                     phase);
}

void DeadlineWatch::arm(std::chrono::steady_clock::time_point deadline, double limit_s) {
  disarm();
  {
    std::lock_guard<std::mutex> lock(mu_);
    armed_ = true;
    deadline_ = deadline;
    limit_s_ = limit_s;
  }
  thread_ = std::thread([this] { watch(); });
}

void DeadlineWatch::set_context(const std::string& what) {
  std::lock_guard<std::mutex> lock(mu_);
  what_ = what;
}

std::string DeadlineWatch::context() {
  std::lock_guard<std::mutex> lock(mu_);
  return what_;
}

DeadlineWatch& deadline_watch() {
  static DeadlineWatch watch;
  return watch;
}

void DeadlineWatch::disarm() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    armed_ = false;
  }
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void DeadlineWatch::watch() {
  std::unique_lock<std::mutex> lock(mu_);
  if (cv_.wait_until(lock, deadline_, [this] { return !armed_; })) return;  // disarmed in time
  if (g_loop_started.load()) return;  // the renderer stops at the deadline itself
  write_all(2, "error: " + time_limit_message(what_, limit_s_, phase_slot().load()) + "\n");
  remove_temporary_outputs();
  ::_exit(kExitTimeLimit);
}

}  // namespace spectrack
