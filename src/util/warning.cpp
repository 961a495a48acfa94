// warning.cpp: see warning.h.
#include "util/warning.h"

#include <atomic>
#include <iostream>
#include <mutex>
#include <set>

namespace spectrack {
namespace {
std::atomic<bool> g_quiet{false};
std::mutex g_mu;
std::set<std::string> g_said;
std::function<void(const std::string&)> g_sink;
}  // namespace

void warn(const std::string& text) {
  if (g_quiet.load()) return;
  std::lock_guard<std::mutex> lock(g_mu);
  if (!g_said.insert(text).second) return;
  if (g_sink) g_sink(text);
  else std::cerr << "warning: " << text << "\n";
}

void set_warning_sink(std::function<void(const std::string& text)> sink) {
  std::lock_guard<std::mutex> lock(g_mu);
  g_sink = std::move(sink);
}

void set_warnings_quiet(bool quiet) { g_quiet.store(quiet); }

}  // namespace spectrack
