// opencl.cpp: see opencl.h. Design notes: the cache entry is a small header (magic, SHA-1 of the
// binary, size) followed by the device binary; anything that does not verify is rebuilt from
// source and rewritten. The key is taken over the assembled source (kernel_source.cpp), so it
// covers the exact text the compiler sees, every included kernel file with it.
#include "device/opencl.h"

#include "util/strings.h"

#include <OpenImageIO/hash.h>
#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <mutex>
#include <thread>
#include <sstream>
#include <cstring>
#include <unistd.h>

namespace spectrack {

const char* cl_error_name(cl_int code) {
  switch (code) {
#define C(x) case x: return #x;
    C(CL_SUCCESS) C(CL_DEVICE_NOT_FOUND) C(CL_DEVICE_NOT_AVAILABLE) C(CL_COMPILER_NOT_AVAILABLE)
    C(CL_MEM_OBJECT_ALLOCATION_FAILURE) C(CL_OUT_OF_RESOURCES) C(CL_OUT_OF_HOST_MEMORY)
    C(CL_PROFILING_INFO_NOT_AVAILABLE) C(CL_MEM_COPY_OVERLAP) C(CL_IMAGE_FORMAT_MISMATCH)
    C(CL_IMAGE_FORMAT_NOT_SUPPORTED) C(CL_BUILD_PROGRAM_FAILURE) C(CL_MAP_FAILURE)
    C(CL_MISALIGNED_SUB_BUFFER_OFFSET) C(CL_EXEC_STATUS_ERROR_FOR_EVENTS_IN_WAIT_LIST)
    C(CL_COMPILE_PROGRAM_FAILURE) C(CL_LINKER_NOT_AVAILABLE) C(CL_LINK_PROGRAM_FAILURE)
    C(CL_INVALID_VALUE) C(CL_INVALID_DEVICE_TYPE) C(CL_INVALID_PLATFORM) C(CL_INVALID_DEVICE)
    C(CL_INVALID_CONTEXT) C(CL_INVALID_QUEUE_PROPERTIES) C(CL_INVALID_COMMAND_QUEUE)
    C(CL_INVALID_HOST_PTR) C(CL_INVALID_MEM_OBJECT) C(CL_INVALID_IMAGE_FORMAT_DESCRIPTOR)
    C(CL_INVALID_IMAGE_SIZE) C(CL_INVALID_SAMPLER) C(CL_INVALID_BINARY) C(CL_INVALID_BUILD_OPTIONS)
    C(CL_INVALID_PROGRAM) C(CL_INVALID_PROGRAM_EXECUTABLE) C(CL_INVALID_KERNEL_NAME)
    C(CL_INVALID_KERNEL_DEFINITION) C(CL_INVALID_KERNEL) C(CL_INVALID_ARG_INDEX) C(CL_INVALID_ARG_VALUE)
    C(CL_INVALID_ARG_SIZE) C(CL_INVALID_KERNEL_ARGS) C(CL_INVALID_WORK_DIMENSION)
    C(CL_INVALID_WORK_GROUP_SIZE) C(CL_INVALID_WORK_ITEM_SIZE) C(CL_INVALID_GLOBAL_OFFSET)
    C(CL_INVALID_EVENT_WAIT_LIST) C(CL_INVALID_EVENT) C(CL_INVALID_OPERATION) C(CL_INVALID_GL_OBJECT)
    C(CL_INVALID_BUFFER_SIZE) C(CL_INVALID_MIP_LEVEL) C(CL_INVALID_GLOBAL_WORK_SIZE)
    C(CL_INVALID_PROPERTY) C(CL_PLATFORM_NOT_FOUND_KHR)
#undef C
    default: return "unknown OpenCL error";
  }
}

void cl_fail(cl_int code, const char* what, const char* file, int line) {
  std::string f = file;
  auto pos = f.find("/src/");
  if (pos != std::string::npos) f = f.substr(pos + 1);
  throw Error(fmt::format("OpenCL error in {}: {} ({}) at {}:{}", what, cl_error_name(code), code, f, line));
}

std::string DeviceInfo::type_name() const {
  if (type & CL_DEVICE_TYPE_GPU) return "GPU";
  if (type & CL_DEVICE_TYPE_CPU) return "CPU";
  if (type & CL_DEVICE_TYPE_ACCELERATOR) return "accelerator";
  return "other";
}

std::vector<DeviceInfo> enumerate_devices(bool warn) {
  // The ICD loader's first clGetPlatformIDs is not safe to run from two threads at once (several
  // devices set up in parallel saw no platform, or crashed): one enumeration at a time.
  static std::mutex mu;
  std::lock_guard<std::mutex> lock(mu);
  std::vector<DeviceInfo> out;
  std::vector<cl::Platform> platforms;
  cl_int err = cl::Platform::get(&platforms);
  if (err != CL_SUCCESS) {
    if (warn) std::cerr << fmt::format("warning: no OpenCL platform ({} {})\n", cl_error_name(err), err);
    return out;
  }
  for (size_t p = 0; p < platforms.size(); ++p) {
    std::vector<cl::Device> devs;
    err = platforms[p].getDevices(CL_DEVICE_TYPE_ALL, &devs);
    std::string pname = platforms[p].getInfo<CL_PLATFORM_NAME>();
    if (err != CL_SUCCESS) {
      if (warn)
        std::cerr << fmt::format("warning: skipping OpenCL platform {} ({}): {} ({})\n", p, pname,
                                 cl_error_name(err), err);
      continue;
    }
    for (size_t d = 0; d < devs.size(); ++d) {
      DeviceInfo i;
      i.platform_index = int(p);
      i.device_index = int(d);
      i.platform_name = pname;
      i.platform_version = platforms[p].getInfo<CL_PLATFORM_VERSION>();
      i.device = devs[d];
      i.name = devs[d].getInfo<CL_DEVICE_NAME>();
      i.vendor = devs[d].getInfo<CL_DEVICE_VENDOR>();
      i.version = devs[d].getInfo<CL_DEVICE_VERSION>();
      i.driver_version = devs[d].getInfo<CL_DRIVER_VERSION>();
      i.type = devs[d].getInfo<CL_DEVICE_TYPE>();
      i.compute_units = devs[d].getInfo<CL_DEVICE_MAX_COMPUTE_UNITS>();
      i.global_mem = devs[d].getInfo<CL_DEVICE_GLOBAL_MEM_SIZE>();
      i.max_alloc = devs[d].getInfo<CL_DEVICE_MAX_MEM_ALLOC_SIZE>();
      i.max_constant = devs[d].getInfo<CL_DEVICE_MAX_CONSTANT_BUFFER_SIZE>();
      // trim the trailing NULs some drivers leave in strings
      for (std::string* s : {&i.name, &i.vendor, &i.version, &i.driver_version, &i.platform_name, &i.platform_version})
        while (!s->empty() && (s->back() == '\0' || s->back() == ' ')) s->pop_back();
      out.push_back(std::move(i));
    }
  }
  return out;
}

static std::string device_list_text(const std::vector<DeviceInfo>& devs) {
  std::string s;
  for (auto& d : devs) s += fmt::format("\n  {}:{}  {} ({})", d.platform_index, d.device_index, d.name, d.type_name());
  return s.empty() ? std::string("\n  (none)") : s;
}

DeviceInfo select_device(const std::string& spec_in) {
  std::string spec = spec_in;
  std::string source = "--device";
  if (spec.empty()) {
    if (const char* e = std::getenv("SPECTRACK_DEVICE")) {
      spec = e;
      source = "SPECTRACK_DEVICE";
    }
  }
  auto devs = enumerate_devices();
  if (devs.empty())
    throw Error("no OpenCL device found: install an OpenCL driver (e.g. Debian's pocl-opencl-icd) and check `spectrack devices`");
  if (spec.empty()) {
    for (auto& d : devs)
      if (d.type & CL_DEVICE_TYPE_GPU) return d;
    return devs.front();
  }
  int p = -1, d = -1;
  char extra = 0;
  if (std::sscanf(spec.c_str(), "%d:%d%c", &p, &d, &extra) == 2) {
    for (auto& i : devs)
      if (i.platform_index == p && i.device_index == d) return i;
    throw Error(fmt::format("{} {}: no such device; devices are:{}", source, spec, device_list_text(devs)));
  }
  for (auto& i : devs)
    if (to_lower(i.name).find(to_lower(spec)) != std::string::npos || to_lower(i.platform_name).find(to_lower(spec)) != std::string::npos)
      return i;
  throw Error(fmt::format("{} '{}': no device name contains it; devices are:{}", source, spec, device_list_text(devs)));
}

// ---------------------------------------------------------------------------------------------
// Build + cache

std::string kernel_cache_dir() {
  const char* off = std::getenv("SPECTRACK_NO_KERNEL_CACHE");
  if (off && std::string(off) != "0" && std::string(off) != "") return "";
  if (const char* d = std::getenv("SPECTRACK_KERNEL_CACHE_DIR")) return d;
  if (const char* x = std::getenv("XDG_CACHE_HOME")) return std::string(x) + "/spectrack/kernels";
  if (const char* h = std::getenv("HOME")) return std::string(h) + "/.cache/spectrack/kernels";
  return "";
}

static std::string sha1_hex(const std::string& data) {
  OIIO::SHA1 h(data.data(), data.size());
  return h.digest();
}

static const char kCacheMagic[8] = {'S', 'T', 'K', 'C', 'A', 'C', 'H', '1'};

static bool read_cache(const std::string& path, std::vector<unsigned char>& bin) {
  std::ifstream f(path, std::ios::binary);
  if (!f) return false;
  char magic[8];
  char digest[40];
  uint64_t size = 0;
  if (!f.read(magic, 8) || std::memcmp(magic, kCacheMagic, 8) != 0) return false;
  if (!f.read(digest, 40) || !f.read(reinterpret_cast<char*>(&size), 8)) return false;
  if (size == 0 || size > (uint64_t(1) << 31)) return false;
  bin.resize(size);
  if (!f.read(reinterpret_cast<char*>(bin.data()), std::streamsize(size))) return false;
  std::string got = sha1_hex(std::string(bin.begin(), bin.end()));
  return got == std::string(digest, 40);
}

static void write_cache(const std::string& path, const std::vector<unsigned char>& bin) {
  std::error_code ec;
  std::filesystem::create_directories(std::filesystem::path(path).parent_path(), ec);
  // unique per process and thread: several devices of one process may write entries at once
  std::string tmp = path + ".tmp" + std::to_string(::getpid()) + "-" +
                    std::to_string(std::hash<std::thread::id>()(std::this_thread::get_id()));
  {
    std::ofstream f(tmp, std::ios::binary);
    if (!f) return;  // an unwritable cache only costs time
    std::string digest = sha1_hex(std::string(bin.begin(), bin.end()));
    uint64_t size = bin.size();
    f.write(kCacheMagic, 8);
    f.write(digest.data(), 40);
    f.write(reinterpret_cast<const char*>(&size), 8);
    f.write(reinterpret_cast<const char*>(bin.data()), std::streamsize(size));
    if (!f) {
      std::filesystem::remove(tmp, ec);
      return;
    }
  }
  std::filesystem::rename(tmp, path, ec);
}

// SPECTRACK_CL_OPTIONS: more build options (measurements: -cl-nv-verbose makes NVIDIA's log list
// each kernel's registers); they are part of the cache key like every option.
static std::string with_extra_options(const std::string& options) {
  const char* e = std::getenv("SPECTRACK_CL_OPTIONS");
  return e && *e ? options + " " + e : options;
}

// SPECTRACK_CL_BUILD_LOG=FILE: the log of a build from source (not from the cache) goes to FILE.
static void keep_build_log(const cl::Program& prog, const DeviceInfo& dev) {
  const char* file = std::getenv("SPECTRACK_CL_BUILD_LOG");
  if (!file || !*file) return;
  std::string log;
  if (prog.getBuildInfo(dev.device, CL_PROGRAM_BUILD_LOG, &log) == CL_SUCCESS) std::ofstream(file, std::ios::app) << log;
}

ProgramBuild build_program(const cl::Context& ctx, const DeviceInfo& dev, const std::string& source,
                           const std::string& options_in, bool quiet) {
  auto t0 = std::chrono::steady_clock::now();
  const std::string options = with_extra_options(options_in);
  ProgramBuild out;
  std::string key = sha1_hex(source + '\0' + options + '\0' + dev.name + '\0' + dev.vendor + '\0' + dev.version + '\0' +
                             dev.driver_version + '\0' + dev.platform_name + '\0' + dev.platform_version + '\0' +
                             SPECTRACK_VERSION);
  std::string dir = kernel_cache_dir();
  if (!dir.empty()) out.cache_file = dir + "/" + key + ".bin";
  std::vector<cl::Device> devs{dev.device};

  if (!out.cache_file.empty()) {
    std::vector<unsigned char> bin;
    if (read_cache(out.cache_file, bin)) {
      cl_int err = CL_SUCCESS;
      std::vector<cl_int> status;
      cl::Program::Binaries bins{bin};
      cl::Program prog(ctx, devs, bins, &status, &err);
      if (err == CL_SUCCESS && prog.build(devs, options.c_str()) == CL_SUCCESS) {
        out.program = prog;
        out.from_cache = true;
        out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        return out;
      }
      if (!quiet) std::cerr << "note: kernel cache entry " << out.cache_file << " is stale or corrupt; rebuilding\n";
    } else if (std::filesystem::exists(out.cache_file)) {
      if (!quiet) std::cerr << "note: kernel cache entry " << out.cache_file << " is corrupt; rebuilding\n";
    }
  }

  cl_int err = CL_SUCCESS;
  cl::Program prog(ctx, source, false, &err);
  ST_CL_CHECK(err, "clCreateProgramWithSource");
  cl_int berr = prog.build(devs, options.c_str());
  if (berr != CL_SUCCESS) {
    std::string log;
    prog.getBuildInfo(dev.device, CL_PROGRAM_BUILD_LOG, &log);
    std::string src_file = (std::filesystem::temp_directory_path() / ("spectrack-kernel-" + key.substr(0, 12) + ".cl")).string();
    std::ofstream(src_file) << source;
    throw Error(fmt::format("kernel build failed on {} ({} {}) with options '{}':\n{}\nassembled source written to {}",
                            dev.name, cl_error_name(berr), berr, options, log, src_file));
  }
  out.program = prog;
  keep_build_log(prog, dev);
  if (!out.cache_file.empty()) {
    std::vector<std::vector<unsigned char>> bins;
    if (prog.getInfo(CL_PROGRAM_BINARIES, &bins) == CL_SUCCESS && !bins.empty() && !bins[0].empty())
      write_cache(out.cache_file, bins[0]);
  }
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace spectrack
