// fuzz_image.cpp: libFuzzer harness for the image reader (src/image read_image, both uses) and the
// environment-map bounds (src/scene/radiance.h). Seeds come from tests/fuzz/make_seeds.cpp.
//
// Contract under test: read_image() on any bytes either returns width x height x 3 pixels within
// the documented limits (a 2-D image of at most 2^28 pixels; for a merge input finite floats
// inside the display window) or throws spectrack::Error naming the file; check_env_map_bounds()
// either accepts or throws Error. The file is named after its magic number (.exr, .png, .hdr,
// .tif, else .img), so OpenImageIO starts with that reader; with "try_all_readers" off it stops
// there (trying ~40 readers per input made the harness crawl at a few runs per second).
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>

#include <OpenImageIO/imageio.h>

#include "image/image.h"
#include "scene/radiance.h"
#include "fuzz_contract.h"

namespace {

namespace fs = std::filesystem;
std::string g_dir, g_file;

void remove_file() {
  std::error_code ec;
  fs::remove_all(g_dir, ec);
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  const char* tmp = std::getenv("TMPDIR");
  g_dir = (fs::path(tmp && *tmp ? tmp : "/tmp") / ("spectrack-fuzz-" + std::to_string(getpid()))).string();
  fs::create_directories(g_dir);
  std::atexit(remove_file);
  OIIO::attribute("threads", 1);  // one thread: reproducible, and no pool left for the leak checker
  OIIO::attribute("try_all_readers", 0);
  return 0;
}

std::string name_for(const uint8_t* d, size_t n) {
  auto starts = [&](const char* m, size_t k) { return n >= k && std::memcmp(d, m, k) == 0; };
  if (starts("\x76\x2f\x31\x01", 4)) return "in.exr";
  if (starts("\x89PNG", 4)) return "in.png";
  if (starts("#?", 2)) return "in.hdr";
  if (starts("II*", 3) || starts("MM\0*", 4)) return "in.tif";
  return "in.img";
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  g_file = g_dir + "/" + name_for(data, size);
  {
    std::ofstream f(g_file, std::ios::binary | std::ios::trunc);
    f.write(reinterpret_cast<const char*>(data), std::streamsize(size));
  }
  for (spectrack::ImageUse use : {spectrack::ImageUse::kEnvironmentMap, spectrack::ImageUse::kFilmPiece}) {
    try {
      spectrack::RgbImage img = spectrack::read_image(g_file, use);
      check(img.width > 0 && img.height > 0, "accepted image has no pixels");
      check(uint64_t(img.width) * uint64_t(img.height) <= (uint64_t(1) << 28), "accepted image over 2^28 pixels");
      check(img.rgb.size() == size_t(img.width) * size_t(img.height) * 3, "pixel buffer size");
      if (use == spectrack::ImageUse::kFilmPiece) {
        for (float v : img.rgb) check(std::isfinite(v), "merge input with a non-finite pixel accepted");
        check(img.extra.size() == size_t(img.width) * size_t(img.height) * img.extra_names.size(), "layer buffer size");
        for (auto& n : img.extra_names) check(spectrack::film_layer_channel(n), "merge input with an unknown channel accepted");
        for (float v : img.extra) check(std::isfinite(v), "merge input with a non-finite layer value accepted");
        check(img.window.x0 >= 0 && img.window.y0 >= 0 && img.window.x0 + int64_t(img.width) <= img.window.full_width &&
                  img.window.y0 + int64_t(img.height) <= img.window.full_height,
              "merge input window outside its display window");
      } else {
        check(img.window.x0 == 0 && img.window.y0 == 0 && img.window.full_width == img.width &&
                  img.window.full_height == img.height,
              "environment map that is not its whole display window accepted");
        try {
          spectrack::check_env_map_bounds("fuzz", g_file, img.rgb, img.width, img.height, 1.0);
        } catch (const spectrack::Error&) {
        }
      }
    } catch (const spectrack::Error& e) {
      if (std::string(e.what()).find(g_file) == std::string::npos)
        finding(std::string("error message does not name the file: ") + e.what());
    }
  }
  return 0;
}
