// opencl.h: the OpenCL runtime layer. Every OpenCL call's status goes through ST_CL_CHECK, which
// throws spectrack::Error naming the call, the error code and the source line. Devices are
// listed over every platform (a platform that fails is skipped with a warning naming the code)
// and chosen by "P:D", by a name substring, or through SPECTRACK_DEVICE. Programs are built from
// the assembled kernel source with a persistent binary cache keyed by a SHA-1 of the source,
// options, device, driver, platform and spectrack version; SPECTRACK_NO_KERNEL_CACHE=1 disables
// it, and a stale or corrupt entry is rebuilt, never trusted. A failed build prints the build
// log and writes the assembled source to a file named in the error.
#pragma once
#include <CL/opencl.hpp>

#include <map>
#include <string>
#include <vector>

#include "util/error.h"

namespace spectrack {

const char* cl_error_name(cl_int code);
[[noreturn]] void cl_fail(cl_int code, const char* what, const char* file, int line);
#define ST_CL_CHECK(call_status, what)                                                   \
  do {                                                                                   \
    cl_int st_cl_status_ = (call_status);                                                \
    if (st_cl_status_ != CL_SUCCESS) ::spectrack::cl_fail(st_cl_status_, what, __FILE__, __LINE__); \
  } while (0)

struct DeviceInfo {
  int platform_index = 0, device_index = 0;
  std::string platform_name, platform_version;
  std::string name, vendor, version, driver_version;
  cl_device_type type = 0;
  cl_uint compute_units = 0;
  cl_ulong global_mem = 0, max_alloc = 0, max_constant = 0;
  cl::Device device;
  std::string type_name() const;
};

// All devices of all platforms; broken platforms are skipped with a warning on stderr.
std::vector<DeviceInfo> enumerate_devices(bool warn = true);
// Picks a device: spec "P:D", or a case-insensitive name substring, or "" (then SPECTRACK_DEVICE,
// then the first GPU, then the first device). Throws Error listing the devices when none matches.
DeviceInfo select_device(const std::string& spec);

struct ProgramBuild {
  cl::Program program;
  double seconds = 0;     // wall time to get a built program
  bool from_cache = false;
  std::string cache_file; // empty if the cache is off
};

// Builds `source` for `dev` with `options`, through the binary cache.
ProgramBuild build_program(const cl::Context& ctx, const DeviceInfo& dev, const std::string& source,
                           const std::string& options, bool quiet);

// The kernel source for a scene: defines, then kernels/renderer.cl with every file it includes,
// each once (kernel_source.cpp), then `extra_files` (kernels/ files not in the renderer's program,
// such as the test probes' probe.cl) with what they include that the renderer does not.
std::string assemble_kernel_source(const std::vector<std::pair<std::string, std::string>>& defines,
                                   const std::vector<std::string>& extra_files = {});

// The named kernels/ files with what they include, each file once, with #line markers; no
// defines and no pragma (the test programs that compile one header with their own kernel).
std::string kernel_files_source(const std::vector<std::string>& roots);
// The same over a given file set (name -> text) instead of the embedded kernels/ files.
std::string kernel_files_source(const std::vector<std::string>& roots,
                                const std::map<std::string, std::string>& files);

// Directory of the kernel binary cache ("" when disabled).
std::string kernel_cache_dir();

}  // namespace spectrack
