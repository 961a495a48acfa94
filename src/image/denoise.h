// denoise.h: Intel Open Image Denoise (OIDN), the denoiser production renderers use, as an
// optional extra.
//
// Design: Debian bookworm does not package OIDN; PyPI's `pyoidn` wheel ships its libraries (OIDN
// 2.5, CPU and GPU devices). spectrack does not link them: it opens libOpenImageDenoise at run time
// (dlopen) through OIDN's C API, so the renderer builds, runs and tests without it, and finds it
// where `pip install pyoidn` put it (the package's oidn/lib folder, asked of /usr/bin/python3
// without importing the package) or where SPECTRACK_OIDN_LIBRARY names the library file. The
// C API rather than the Python module: no Python interpreter, numpy or image copy in the render's
// process, and the same calls work with a library built from source. The filter is OIDN's "RT"
// (ray-traced images), HDR, on the CPU device (the host's images are shared with it, no copies),
// with the albedo image as its auxiliary input when given.
#pragma once
#include <string>
#include <vector>

namespace spectrack {

// The library file to open (SPECTRACK_OIDN_LIBRARY when set, else pyoidn's), or "" when that file
// does not exist (the message of denoise_unavailable then).
std::string find_oidn_library();
// What to do to get it: install pyoidn, or set SPECTRACK_OIDN_LIBRARY.
std::string denoise_unavailable();

// Denoises width x height linear RGB (3 floats per pixel, row 0 at the top), with `albedo` (the
// same layout; empty: none) as auxiliary input. Throws UsageError (denoise_unavailable) when the
// library is missing, Error with OIDN's message when it fails.
std::vector<float> denoise(const std::vector<float>& rgb, const std::vector<float>& albedo, int width, int height);

}  // namespace spectrack
