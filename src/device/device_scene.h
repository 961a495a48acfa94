// device_scene.h: a packed scene on one OpenCL device, and named, profiled kernel launches.
//
// Design: DeviceScene owns the device's context and queue and the scene's read-only buffers
// (st_scene constants, NanoVDB grids, majorant cells, environment data) uploaded from a
// PackedScene. The renderer and the test probes (device/probe.h) each build their own program
// on it and launch through a KernelLauncher, which names every launch and sums its OpenCL
// profiling time per kernel name (--stats-json "kernels").
#pragma once
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "device/opencl.h"
#include "integrator/renderer.h"
#include "scene/scene_pack.h"

namespace spectrack {

struct DeviceScene {
  DeviceInfo dev;
  cl::Context ctx;
  cl::CommandQueue queue;  // in order, with profiling
  PackedScene packed;     // its grid, majorant and environment buffers are released once uploaded
  double scene_bytes = 0;  // what they take on the device
  // the kernel source defines this scene's programs are built with (feature mask, media count)
  std::vector<std::pair<std::string, std::string>> defines;
  cl::Buffer b_scene, b_grids, b_maj, b_env;

  // A buffer of `bytes` (at least 16; a shorter host copy is padded, never over-read), refused by
  // name when the device cannot allocate it in one piece.
  cl::Buffer buffer(cl_mem_flags flags, size_t bytes, const void* host, const char* what) const;
  // Uploads packed.st again (after a change of its per-render fields).
  void write_scene_constants();
};

// Opens a context and queue on the device `spec` names (select_device) and uploads `packed`.
DeviceScene upload_scene(const std::string& device_spec, PackedScene packed,
                         std::vector<std::pair<std::string, std::string>> defines);

class KernelLauncher {
 public:
  KernelLauncher(cl::CommandQueue queue, cl::Program program) : queue_(std::move(queue)), program_(std::move(program)) {}
  cl::Kernel& kernel(const std::string& name);
  // Enqueues a named 1D launch of n items (none for n = 0) and keeps its event for profiling.
  void launch(const std::string& name, size_t n);
  // Enqueues one work-group of the real size whose items must all return at once (the caller
  // binds arguments that say so: queue sizes of 0), so that a driver that compiles a kernel at its
  // first launch per work-group size (PoCL) does it now. Not recorded in times().
  void warm(const std::string& name);
  // Adds the finished launches' device time to times(); those still queued or running stay for a
  // later call.
  void collect_profiling();
  std::map<std::string, KernelTime>& times() { return times_; }
  static constexpr size_t kLocalSize = 64;  // every launch's work-group size

 private:
  struct Record {
    std::string name;
    cl::Event event;
  };
  cl::CommandQueue queue_;
  cl::Program program_;
  std::map<std::string, cl::Kernel> kernels_;
  std::vector<Record> pending_;
  std::map<std::string, KernelTime> times_;
};

}  // namespace spectrack
