// image_write.cpp: writing EXR and PNG images (image.h), and the checks of output names made
// before rendering. sRGB encoding for PNG previews is done here (the OETF of IEC 61966-2-1) so
// that the preview matches what an EXR viewer shows for the same linear values.
//
// Design: OpenImageIO encodes into an IOProxy that hands every byte to an OutputFile
// (util/output_file.h): the image goes to a temporary file in the output's folder, every write is
// checked there (libpng's own writes go unchecked), and the file is renamed over the final name
// only once OpenImageIO and every write have succeeded. A full disk, a quota or a file-size limit
// therefore leaves no partial file under the final name, and an Error that names the file and the
// reason.
#include "image/image.h"
#include "image/image_open.h"
#include "image/output_proxy.h"
#include "util/files.h"
#include "util/output_file.h"
#include "util/strings.h"

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>
#include <fmt/format.h>
#include <sys/stat.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <mutex>

namespace spectrack {
namespace {

std::string extension(const std::string& path) {
  std::string e = lower_extension(path);
  return e;
}

}  // namespace

float srgb_encode(float v) {
  if (!(v > 0.0f)) return 0.0f;
  if (v >= 1.0f) return 1.0f;
  return v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
}

namespace {

// Encodes `pixels` (of `type`, as `spec` says) into `path` through an OutputFile.
void encode(const std::string& path, const OIIO::ImageSpec& spec, OIIO::TypeDesc type, const void* pixels) {
  OutputFile file(path);
  OutputProxy proxy(file);
  auto out = OIIO::ImageOutput::create(path, &proxy);
  if (!out) throw Error(fmt::format("{}: cannot create image writer: {}", path, OIIO::geterror()));
  bool ok = out->open(path, spec) && out->write_image(type, pixels);
  ok = out->close() && ok;
  if (!ok || out->has_error()) file.fail(out->geterror());  // a failed write's own reason, when there is one, stays first
  if (file.size() == 0) file.fail("the image writer wrote nothing through spectrack's output file");
  out.reset();
  file.commit();
}

void set_metadata(OIIO::ImageSpec& spec, const Metadata& meta) {
  for (auto& [k, v] : meta) {
    std::string key = "spectrack:" + k;
    if (auto s = std::get_if<std::string>(&v)) spec.attribute(key, *s);
    else if (auto i = std::get_if<int>(&v)) spec.attribute(key, *i);
    else if (auto f = std::get_if<float>(&v)) spec.attribute(key, *f);
  }
}

}  // namespace

void set_exr_spec(OIIO::ImageSpec& spec, const Metadata& meta, const PixelWindow& window, const ExrOptions& exr) {
  set_metadata(spec, meta);
  spec.attribute("compression", exr.compression);
  if (window.full_width > 0) {
    spec.x = window.x0;
    spec.y = window.y0;
    spec.full_x = spec.full_y = 0;
    spec.full_width = window.full_width;
    spec.full_height = window.full_height;
  }
}

void check_output_path(const std::string& path) {
  struct stat st;
  if (::stat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode))
    throw Error(fmt::format("{}: is {}; an image is written to a regular file named .exr or .png", path,
                            kind_of(st.st_mode)));
  const std::string e = extension(path);
  if (e.empty())
    throw Error(fmt::format("{}: has no extension; the image format follows it: name the file .exr or .png", path));
  if (e != ".exr" && e != ".png")
    throw Error(fmt::format("{}: unsupported output format '{}' (use .exr or .png)", path, e));
  check_writable_file(path);
}

void check_writable_file(const std::string& path) { check_creatable_file(path); }

void write_exr_channels(const std::string& path, int width, int height, const std::vector<std::string>& names,
                        const std::vector<float>& px, const Metadata& meta, const PixelWindow& window,
                        const ExrOptions& exr) {
  check_output_path(path);
  if (extension(path) != ".exr") throw Error(fmt::format("{}: internal: film layers need an EXR", path));
  if (names.empty() || px.size() != size_t(width) * size_t(height) * names.size())
    throw Error(fmt::format("{}: internal: image size mismatch", path));
  OIIO::ImageSpec spec(width, height, int(names.size()), exr.half ? OIIO::TypeDesc::HALF : OIIO::TypeDesc::FLOAT);
  spec.channelnames = names;
  spec.alpha_channel = -1;
  for (size_t c = 0; c < names.size(); ++c)
    if (names[c] == "A") spec.alpha_channel = int(c);
  set_exr_spec(spec, meta, window, exr);
  encode(path, spec, OIIO::TypeDesc::FLOAT, px.data());
}

void write_image(const std::string& path, int width, int height, const std::vector<float>& rgb, const Metadata& meta,
                 const PixelWindow& window, const ExrOptions& exr) {
  check_output_path(path);
  if (rgb.size() != size_t(width) * size_t(height) * 3) throw Error(fmt::format("{}: internal: image size mismatch", path));
  if (extension(path) != ".png") {
    write_exr_channels(path, width, height, {"R", "G", "B"}, rgb, meta, window, exr);
    return;
  }
  OIIO::ImageSpec spec(width, height, 3, OIIO::TypeDesc::UINT8);
  set_metadata(spec, meta);
  std::vector<unsigned char> px(rgb.size());
  for (size_t i = 0; i < rgb.size(); ++i) px[i] = (unsigned char)std::lround(srgb_encode(rgb[i]) * 255.0f);
  encode(path, spec, OIIO::TypeDesc::UINT8, px.data());
}

}  // namespace spectrack
