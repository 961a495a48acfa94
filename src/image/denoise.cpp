// denoise.cpp: see denoise.h.
#include "image/denoise.h"

#include <dlfcn.h>
#include <fmt/format.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>

#include "util/error.h"

namespace spectrack {
namespace {

// OIDN 2's C API (OpenImageDenoise/oidn.h), the few calls used here.
using Device = void*;
using Filter = void*;
constexpr int kDeviceCpu = 1;   // OIDN_DEVICE_TYPE_CPU
constexpr int kFormatFloat3 = 3;  // OIDN_FORMAT_FLOAT3
struct Api {
  Device (*new_device)(int);
  void (*commit_device)(Device);
  void (*release_device)(Device);
  int (*device_error)(Device, const char**);
  Filter (*new_filter)(Device, const char*);
  void (*set_image)(Filter, const char*, void*, int, size_t, size_t, size_t, size_t, size_t);
  void (*set_bool)(Filter, const char*, bool);
  void (*commit_filter)(Filter);
  void (*execute_filter)(Filter);
  void (*release_filter)(Filter);
};

template <class F>
void symbol(void* lib, const char* name, F* out, const std::string& path) {
  *out = reinterpret_cast<F>(dlsym(lib, name));
  if (!*out) throw Error(fmt::format("{}: not an Open Image Denoise 2 library (no {})", path, name));
}

Api load_api(const std::string& path) {
  void* lib = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);  // kept open for the process
  if (!lib) throw UsageError(fmt::format("cannot open {}: {}; {}", path, dlerror(), denoise_unavailable()));
  Api a{};
  symbol(lib, "oidnNewDevice", &a.new_device, path);
  symbol(lib, "oidnCommitDevice", &a.commit_device, path);
  symbol(lib, "oidnReleaseDevice", &a.release_device, path);
  symbol(lib, "oidnGetDeviceError", &a.device_error, path);
  symbol(lib, "oidnNewFilter", &a.new_filter, path);
  symbol(lib, "oidnSetSharedFilterImage", &a.set_image, path);
  symbol(lib, "oidnSetFilterBool", &a.set_bool, path);
  symbol(lib, "oidnCommitFilter", &a.commit_filter, path);
  symbol(lib, "oidnExecuteFilter", &a.execute_filter, path);
  symbol(lib, "oidnReleaseFilter", &a.release_filter, path);
  return a;
}

// Where pip put pyoidn, asked of the system's Python without importing the package.
std::string pyoidn_library() {
  const char* cmd =
      "/usr/bin/python3 -c \"import importlib.util, os; s = importlib.util.find_spec('pyoidn'); "
      "print(os.path.join(os.path.dirname(s.origin), 'oidn', 'lib', 'libOpenImageDenoise.so.2') if s else '')\" "
      "2>/dev/null";
  std::unique_ptr<FILE, int (*)(FILE*)> p(popen(cmd, "r"), pclose);
  if (!p) return "";
  char buf[4096] = {};
  std::string out;
  while (fgets(buf, sizeof buf, p.get())) out += buf;
  while (!out.empty() && (out.back() == '\n' || out.back() == '\r')) out.pop_back();
  return out;
}

}  // namespace

std::string find_oidn_library() {
  std::error_code ec;
  if (const char* e = std::getenv("SPECTRACK_OIDN_LIBRARY"); e && *e) return std::filesystem::exists(e, ec) ? e : "";
  const std::string p = pyoidn_library();
  return !p.empty() && std::filesystem::exists(p, ec) ? p : "";
}

std::string denoise_unavailable() {
  const char* e = std::getenv("SPECTRACK_OIDN_LIBRARY");
  return std::string("--denoise needs Intel Open Image Denoise") +
         (e && *e ? fmt::format(" (SPECTRACK_OIDN_LIBRARY names '{}', which does not exist)", e) : std::string()) +
         ": install it with `/usr/bin/python3 -m pip install --user pyoidn` (its wheel ships the libraries; add "
         "--break-system-packages on Debian), or set SPECTRACK_OIDN_LIBRARY to a libOpenImageDenoise.so.2 "
         "(docs/cli.md#denoising)";
}

std::vector<float> denoise(const std::vector<float>& rgb, const std::vector<float>& albedo, int width, int height) {
  const size_t n = size_t(width) * size_t(height) * 3;
  if (rgb.size() != n || (!albedo.empty() && albedo.size() != n)) throw Error("internal: denoise: image sizes differ");
  const std::string path = find_oidn_library();
  if (path.empty()) throw UsageError(denoise_unavailable());
  static const Api api = load_api(path);
  Device dev = api.new_device(kDeviceCpu);
  if (!dev) throw Error(fmt::format("{}: no Open Image Denoise CPU device", path));
  std::unique_ptr<void, void (*)(void*)> dev_guard(dev, api.release_device);
  api.commit_device(dev);
  Filter f = api.new_filter(dev, "RT");
  std::vector<float> out(n), color(rgb), aux(albedo);
  if (f) {
    std::unique_ptr<void, void (*)(void*)> filter_guard(f, api.release_filter);
    api.set_image(f, "color", color.data(), kFormatFloat3, size_t(width), size_t(height), 0, 0, 0);
    if (!aux.empty()) api.set_image(f, "albedo", aux.data(), kFormatFloat3, size_t(width), size_t(height), 0, 0, 0);
    api.set_image(f, "output", out.data(), kFormatFloat3, size_t(width), size_t(height), 0, 0, 0);
    api.set_bool(f, "hdr", true);
    api.commit_filter(f);
    api.execute_filter(f);
  }
  const char* message = nullptr;
  if (api.device_error(dev, &message) != 0 || !f)
    throw Error(fmt::format("Open Image Denoise ({}) failed: {}", path, message ? message : "no filter"));
  return out;
}

}  // namespace spectrack
