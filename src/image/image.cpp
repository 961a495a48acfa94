// image.cpp: see image.h. sRGB encoding for PNG previews is done here (the OETF of IEC 61966-2-1)
// so that the preview matches what an EXR viewer shows for the same linear values.
#include "image/image.h"

#include <OpenImageIO/imageio.h>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <unistd.h>

namespace spectrack {

static std::string extension(const std::string& path) {
  std::string e = std::filesystem::path(path).extension().string();
  std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return e;
}

void check_output_path(const std::string& path) {
  std::string e = extension(path);
  if (e != ".exr" && e != ".png")
    throw Error(fmt::format("{}: unsupported output format '{}' (use .exr or .png)", path, e));
  check_writable_file(path);
}

void check_writable_file(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) throw Error(fmt::format("{}: is a folder, not a file", path));
  std::filesystem::path dir = std::filesystem::path(path).parent_path();
  if (dir.empty()) dir = ".";
  if (!std::filesystem::is_directory(dir, ec))
    throw Error(fmt::format("{}: output folder {} does not exist", path, dir.string()));
  if (::access(dir.c_str(), W_OK) != 0)
    throw Error(fmt::format("{}: output folder {} is not writable", path, dir.string()));
  if (std::filesystem::exists(path, ec) && ::access(path.c_str(), W_OK) != 0)
    throw Error(fmt::format("{}: output file is not writable", path));
}

static float srgb_encode(float v) {
  if (!(v > 0.0f)) return 0.0f;
  if (v >= 1.0f) return 1.0f;
  return v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
}

void write_image(const std::string& path, int width, int height, const std::vector<float>& rgb, const Metadata& meta,
                 const PixelWindow& window) {
  check_output_path(path);
  if (rgb.size() != size_t(width) * size_t(height) * 3) throw Error(fmt::format("{}: internal: image size mismatch", path));
  bool png = extension(path) == ".png";
  auto out = OIIO::ImageOutput::create(path);
  if (!out) throw Error(fmt::format("{}: cannot create image writer: {}", path, OIIO::geterror()));
  OIIO::ImageSpec spec(width, height, 3, png ? OIIO::TypeDesc::UINT8 : OIIO::TypeDesc::FLOAT);
  for (auto& [k, v] : meta) {
    std::string key = "spectrack:" + k;
    if (auto s = std::get_if<std::string>(&v)) spec.attribute(key, *s);
    else if (auto i = std::get_if<int>(&v)) spec.attribute(key, *i);
    else if (auto f = std::get_if<float>(&v)) spec.attribute(key, *f);
  }
  if (!png) {
    spec.attribute("compression", "zip");
    if (window.full_width > 0) {
      spec.x = window.x0;
      spec.y = window.y0;
      spec.full_x = spec.full_y = 0;
      spec.full_width = window.full_width;
      spec.full_height = window.full_height;
    }
  }
  if (!out->open(path, spec)) throw Error(fmt::format("{}: cannot open for writing: {}", path, out->geterror()));
  bool ok;
  if (png) {
    std::vector<unsigned char> px(rgb.size());
    for (size_t i = 0; i < rgb.size(); ++i) px[i] = (unsigned char)std::lround(srgb_encode(rgb[i]) * 255.0f);
    ok = out->write_image(OIIO::TypeDesc::UINT8, px.data());
  } else {
    ok = out->write_image(OIIO::TypeDesc::FLOAT, rgb.data());
  }
  if (!ok || !out->close()) throw Error(fmt::format("{}: write failed: {}", path, out->geterror()));
}

RgbImage read_image(const std::string& path) {
  auto in = OIIO::ImageInput::open(path);
  if (!in) throw Error(fmt::format("{}: cannot read image: {}", path, OIIO::geterror()));
  const OIIO::ImageSpec& spec = in->spec();
  RgbImage img;
  img.width = spec.width;
  img.height = spec.height;
  img.format = in->format_name();
  img.window.x0 = spec.x - spec.full_x;
  img.window.y0 = spec.y - spec.full_y;
  img.window.full_width = spec.full_width > 0 ? spec.full_width : spec.width;
  img.window.full_height = spec.full_height > 0 ? spec.full_height : spec.height;
  int nc = spec.nchannels;
  if (img.width <= 0 || img.height <= 0 || nc <= 0 || size_t(img.width) * size_t(img.height) > (size_t(1) << 28))
    throw Error(fmt::format("{}: unsupported image size {}x{}x{}", path, img.width, img.height, nc));
  std::vector<float> px(size_t(img.width) * img.height * nc);
  if (!in->read_image(0, 0, 0, nc, OIIO::TypeDesc::FLOAT, px.data()))
    throw Error(fmt::format("{}: cannot read pixels: {}", path, in->geterror()));
  img.rgb.resize(size_t(img.width) * img.height * 3);
  for (size_t i = 0; i < size_t(img.width) * img.height; ++i)
    for (int c = 0; c < 3; ++c) img.rgb[i * 3 + c] = px[i * nc + std::min(c, nc - 1)];
  for (const auto& a : spec.extra_attribs) {
    std::string n = a.name().string();
    if (n.rfind("spectrack:", 0) != 0) continue;
    std::string k = n.substr(10);
    if (a.type() == OIIO::TypeDesc::INT) img.meta[k] = a.get_int();
    else if (a.type() == OIIO::TypeDesc::FLOAT) img.meta[k] = a.get_float();
    else img.meta[k] = a.get_string();
  }
  in->close();
  return img;
}

}  // namespace spectrack
