// device_scene.cpp: see device_scene.h.
#include "device/device_scene.h"
#include "integrator/memory_budget.h"

#include <fmt/format.h>

#include <cstring>

namespace spectrack {

cl::Buffer DeviceScene::buffer(cl_mem_flags flags, size_t bytes, const void* host, const char* what) const {
  cl_int err = CL_SUCCESS;
  std::vector<unsigned char> padded;
  if (bytes < 16) {
    if (host) {
      padded.assign(16, 0);
      std::memcpy(padded.data(), host, bytes);
      host = padded.data();
    }
    bytes = 16;
  }
  if (bytes > dev.max_alloc)
    throw Error(fmt::format("{} needs {:.1f} MiB in one buffer but device '{}' allows at most {:.1f} MiB per "
                            "allocation (global memory {:.1f} MiB); {}choose another device with --device",
                            what, bytes / 1048576.0, dev.name, dev.max_alloc / 1048576.0, dev.global_mem / 1048576.0,
                            std::string(what).find("--") != std::string::npos ? "lower the option named, or " : ""));
  cl::Buffer b(ctx, flags | (host ? CL_MEM_COPY_HOST_PTR : 0), bytes, const_cast<void*>(host), &err);
  ST_CL_CHECK(err, (std::string("clCreateBuffer(") + what + ")").c_str());
  return b;
}

void DeviceScene::write_scene_constants() {
  ST_CL_CHECK(queue.enqueueWriteBuffer(b_scene, CL_TRUE, 0, sizeof(packed.st), &packed.st), "write scene constants");
}

DeviceScene upload_scene(const std::string& device_spec, PackedScene packed,
                         std::vector<std::pair<std::string, std::string>> defines) {
  DeviceScene d;
  d.dev = select_device(device_spec);
  cl_int err = CL_SUCCESS;
  d.ctx = cl::Context(d.dev.device, nullptr, nullptr, nullptr, &err);
  ST_CL_CHECK(err, "clCreateContext");
  d.queue = cl::CommandQueue(d.ctx, d.dev.device, CL_QUEUE_PROFILING_ENABLE, &err);
  ST_CL_CHECK(err, "clCreateCommandQueue");
  d.packed = std::move(packed);
  d.defines = std::move(defines);
  const PackedScene& p = d.packed;
  if (sizeof(p.st) > d.dev.max_constant)
    throw Error(fmt::format("device '{}' has {} bytes of constant memory; spectrack needs {}", d.dev.name,
                            d.dev.max_constant, sizeof(p.st)));
  // the scene's buffers against the device (and, for a CPU device, the host whose memory it uses)
  const double scene_bytes = d.scene_bytes = (p.grid_words.size() + p.maj_cells.size() + p.env_data.size()) * 4.0;
  const std::string what = fmt::format("the scene's grids, majorants and environment maps ({:.1f} MiB)",
                                       scene_bytes / 1048576.0);
  if (scene_bytes > double(d.dev.global_mem))
    throw Error(fmt::format("{} do not fit device '{}' ({:.1f} MiB of global memory); choose another device with "
                            "--device", what, d.dev.name, d.dev.global_mem / 1048576.0));
  if (d.dev.type & CL_DEVICE_TYPE_CPU) check_host_memory(scene_bytes, what, "free host memory, or choose another device with --device");
  d.b_scene = d.buffer(CL_MEM_READ_ONLY, sizeof(p.st), &p.st, "scene constants");
  d.b_grids = d.buffer(CL_MEM_READ_ONLY, p.grid_words.size() * 4, p.grid_words.data(), "NanoVDB grids");
  d.b_maj = d.buffer(CL_MEM_READ_ONLY, p.maj_cells.size() * 4, p.maj_cells.data(), "majorant grids");
  d.b_env = d.buffer(CL_MEM_READ_ONLY, p.env_data.size() * 4, p.env_data.data(), "environment maps");
  // the device holds them now (CL_MEM_COPY_HOST_PTR copies at creation): the host copies go
  std::vector<uint32_t>().swap(d.packed.grid_words);
  std::vector<float>().swap(d.packed.maj_cells);
  std::vector<float>().swap(d.packed.env_data);
  return d;
}

cl::Kernel& KernelLauncher::kernel(const std::string& name) {
  auto it = kernels_.find(name);
  if (it != kernels_.end()) return it->second;
  cl_int err = CL_SUCCESS;
  cl::Kernel k(program_, name.c_str(), &err);
  ST_CL_CHECK(err, ("clCreateKernel(" + name + ")").c_str());
  return kernels_[name] = k;
}

void KernelLauncher::launch(const std::string& name, size_t n) {
  if (n == 0) return;
  // A fixed work-group size: PoCL JIT-compiles a kernel once per work-group size, so letting the
  // driver choose one per item count would recompile on most launches.
  const size_t local = kLocalSize;
  size_t global = (n + local - 1) / local * local;
  cl::Event ev;
  cl_int err = queue_.enqueueNDRangeKernel(kernel(name), cl::NullRange, cl::NDRange(global), cl::NDRange(local),
                                           nullptr, &ev);
  ST_CL_CHECK(err, ("clEnqueueNDRangeKernel(" + name + ")").c_str());
  pending_.push_back({name, ev});
}

void KernelLauncher::warm(const std::string& name) {
  cl_int err = queue_.enqueueNDRangeKernel(kernel(name), cl::NullRange, cl::NDRange(kLocalSize), cl::NDRange(kLocalSize));
  ST_CL_CHECK(err, ("clEnqueueNDRangeKernel(" + name + ", warm-up)").c_str());
}

void KernelLauncher::collect_profiling() {
  std::vector<Record> running;  // launched but not finished: collected at a later call
  for (auto& r : pending_) {
    cl_int status = CL_COMPLETE;
    if (r.event.getInfo(CL_EVENT_COMMAND_EXECUTION_STATUS, &status) == CL_SUCCESS && status > CL_COMPLETE) {
      running.push_back(std::move(r));
      continue;
    }
    cl_ulong a = 0, b = 0;
    if (r.event.getProfilingInfo(CL_PROFILING_COMMAND_START, &a) == CL_SUCCESS &&
        r.event.getProfilingInfo(CL_PROFILING_COMMAND_END, &b) == CL_SUCCESS && b >= a)
      times_[r.name].seconds += double(b - a) * 1e-9;
    times_[r.name].launches += 1;
  }
  pending_ = std::move(running);
}

}  // namespace spectrack
