// image.cpp: see image.h. Reading images; image_write.cpp writes them.
#include "image/image.h"
#include "image/extra_channels.h"
#include "image/image_open.h"
#include "scene/scene.h"
#include "util/files.h"
#include "util/strings.h"

#include <OpenImageIO/imageio.h>
#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <memory>

namespace spectrack {

// (and the channels of image/extra_channels.h: a merge refuses an adaptive film, drops the denoised beauty)
bool film_layer_channel(const std::string& name) {
  if (name == kCollisionChannel || name == kSamplesChannel) return true;
  for (const char* c : kDenoisedChannels)
    if (name == c) return true;
  for (int k = 0; k < ST_AOV_COUNT; ++k)
    for (const std::string& c : aov_exr_channels(k))
      if (name == c) return true;
  return false;
}

static float srgb_decode(float v) {
  if (!(v > 0.0f)) return 0.0f;
  return v <= 0.04045f ? v / 12.92f : std::pow((v + 0.055f) / 1.055f, 2.4f);
}

// "R", "G", "B" or a layer's "diffuse.R": the last component, case-insensitive.
static std::string channel_base(const std::string& name) {
  std::string b = name.substr(name.rfind('.') == std::string::npos ? 0 : name.rfind('.') + 1);
  std::transform(b.begin(), b.end(), b.begin(), [](unsigned char c) { return char(std::toupper(c)); });
  return b;
}

static std::string channel_list(const OIIO::ImageSpec& spec) {
  std::string s;
  for (int c = 0; c < spec.nchannels && c < 16; ++c)
    s += (c ? ", " : "") + (c < int(spec.channelnames.size()) ? spec.channelnames[c] : std::string("?"));
  if (spec.nchannels > 16) s += ", ...";
  return s;
}

// The value of EXR attribute `name` of type `type`, which claims `size` bytes at f's position:
// a fixed-size type must claim its size, and a channel list or preview (which OpenEXR reads by
// their own structure) must fill the claim exactly. Leaves f where the value starts.
static void check_exr_attribute_value(std::istream& f, const std::string& name, const std::string& type, int32_t size,
                                      size_t max_name, const std::function<void(const std::string&)>& fail) {
  // OpenEXR reads a fixed-size type's value whatever size the attribute claims, so a claim
  // that disagrees would make this walk and OpenEXR's part ways (the rest of the header read
  // as other attributes, one of them a 2 GB string)
  static const std::pair<const char*, int32_t> fixed[] = {
      {"box2i", 16}, {"box2f", 16}, {"v2i", 8},   {"v2f", 8},        {"v2d", 16},          {"v3i", 12},
      {"v3f", 12},   {"v3d", 24},   {"int", 4},   {"float", 4},      {"double", 8},        {"compression", 1},
      {"lineOrder", 1}, {"envmap", 1}, {"m33f", 36}, {"m33d", 72}, {"m44f", 64},  {"m44d", 128},
      {"chromaticities", 32}, {"keycode", 28}, {"timecode", 8}, {"rational", 8}, {"tiledesc", 9},
      {"deepImageState", 1}};
  for (const auto& [t, n] : fixed)
    if (type == t && size != n)
      fail(fmt::format("attribute '{}' claims {} bytes, but a {} value has {}", name, size, type, n));
  if (type == "chlist" || type == "preview") {
    // OpenEXR reads these by their own structure, not by the claimed size: a channel list up to
    // its empty name (each channel: name, then 16 bytes), a preview's width x height x 4 bytes.
    // Walk them the same way; the structure must fill the claim exactly.
    const std::streamoff value_at = f.tellg();
    uint64_t used = 0;
    auto need = [&](uint64_t n) {
      if (used + n > uint64_t(size))
        fail(fmt::format("attribute '{}' ({}) runs past the {} bytes it claims", name, type, size));
      used += n;
    };
    if (type == "chlist") {
      for (int channels = 0;; ++channels) {
        if (channels > 4096) fail(fmt::format("attribute '{}' lists more than 4096 channels", name));
        need(1);
        const int c = f.get();
        if (c == EOF) fail(fmt::format("the file ends inside attribute '{}'", name));
        if (c == 0) break;  // the list's end
        for (int k = 0;; ++k) {
          need(1);
          const int ch = f.get();
          if (ch == EOF) fail(fmt::format("the file ends inside attribute '{}'", name));
          if (ch == 0) break;
          if (k >= int(max_name)) fail(fmt::format("attribute '{}' has a channel name over {} characters", name, max_name));
        }
        need(16);
        f.seekg(16, std::ios::cur);
      }
    } else {
      unsigned char wh[8];
      need(8);
      if (!f.read(reinterpret_cast<char*>(wh), 8)) fail(fmt::format("the file ends inside attribute '{}'", name));
      const uint64_t pw = uint64_t(wh[0]) | uint64_t(wh[1]) << 8 | uint64_t(wh[2]) << 16 | uint64_t(wh[3]) << 24;
      const uint64_t ph = uint64_t(wh[4]) | uint64_t(wh[5]) << 8 | uint64_t(wh[6]) << 16 | uint64_t(wh[7]) << 24;
      if (ph != 0 && pw > uint64_t(size) / 4 / ph)  // (no overflow: checked before the product)
        fail(fmt::format("attribute '{}' (preview) of {}x{} pixels runs past the {} bytes it claims", name, pw, ph, size));
      need(pw * ph * 4);
    }
    if (used != uint64_t(size))
      fail(fmt::format("attribute '{}' ({}) claims {} bytes but its contents take {}", name, type, size, used));
    f.clear();
    f.seekg(value_at);
  }
}

// The most pixels a byte of an image file is taken to hold (here and in open_checked).
constexpr double kMaxPixelsPerFileByte = 4096;

// OpenEXR sizes a decompressor's buffer by the data window's width times the lines of one block
// (up to 256 for DWAB) when the file is opened, before any pixel is read (2 GB for a 1-kB file,
// fuzz_image): a data window claiming more than kMaxPixelsPerFileByte a byte, its height counted
// as at least 256 lines, is refused first. The value is read, and the stream put back.
static void check_exr_data_window(std::istream& f, uint64_t file_bytes, const std::function<void(const std::string&)>& fail) {
  const std::streamoff value_at = f.tellg();
  unsigned char b[16];
  if (!f.read(reinterpret_cast<char*>(b), 16)) fail("the file ends inside attribute 'dataWindow'");
  f.seekg(value_at);
  int32_t w[4];
  for (int i = 0; i < 4; ++i)
    w[i] = int32_t(uint32_t(b[4 * i]) | uint32_t(b[4 * i + 1]) << 8 | uint32_t(b[4 * i + 2]) << 16 | uint32_t(b[4 * i + 3]) << 24);
  const double width = double(w[2]) - w[0] + 1, height = double(w[3]) - w[1] + 1;
  if (width * std::max(height, 256.0) > kMaxPixelsPerFileByte * double(file_bytes) + double(1 << 20))
    fail(fmt::format("its data window ({} x {} pixels) claims more than {} pixels a byte of its {}-byte file", width,
                     height, kMaxPixelsPerFileByte, file_bytes));
}

// OpenEXR allocates what a header attribute claims (a 2 GB string for a damaged "capDate") before
// it finds the file too short. Walk the EXR header(s) first: each attribute is name\0 type\0 int32
// size, then size bytes (skipped, not read); a multi-part file has several headers, each ended by
// a null byte, and an empty header after the last. Every claim must fit in the bytes the file has;
// the message names the attribute. Returns normally for a header that is well formed up to the
// offset tables.
static void check_exr_header(const std::string& path, std::istream& f, uint64_t file_bytes) {
  auto fail = [&](const std::string& reason) { throw Error(fmt::format("{}: damaged OpenEXR header: {}", path, reason)); };
  unsigned char v[8] = {};
  f.clear();
  f.seekg(0);
  if (!f.read(reinterpret_cast<char*>(v), 8)) fail("the file ends inside its 8-byte magic number and version");
  const uint32_t version = uint32_t(v[4]) | uint32_t(v[5]) << 8 | uint32_t(v[6]) << 16 | uint32_t(v[7]) << 24;
  const bool multipart = version & 0x1000u;
  const size_t max_name = (version & 0x400u) ? 255 : 31;
  uint64_t at = 8;  // bytes of the file walked
  auto read_name = [&](const char* what) -> std::string {
    std::string s;
    for (;;) {
      const int c = f.get();
      if (c == EOF) fail(fmt::format("the file ends inside an attribute {}", what));
      ++at;
      if (c == 0) return s;
      if (s.size() >= max_name) fail(fmt::format("an attribute {} is longer than {} characters", what, max_name));
      s += char(c);
    }
  };
  auto header_ends = [&](int part) {  // the next byte is the null that ends a header
    const int c = f.peek();
    if (c == EOF) fail(fmt::format("the file ends inside header {}", part));
    return c == 0;
  };
  for (int part = 0;; ++part) {
    if (header_ends(part)) {  // an empty header: in a multi-part file, the end of the header list
      f.get(), ++at;
      if (!multipart || part > 0) break;
      fail("a multi-part file whose first header is empty");
    }
    for (int attrs = 0; !header_ends(part); ++attrs) {
      if (attrs >= 4096) fail(fmt::format("header {} has more than 4096 attributes", part));
      std::string name = read_name("name");
      std::string type = read_name("type");
      unsigned char b[4];
      if (!f.read(reinterpret_cast<char*>(b), 4)) fail(fmt::format("the file ends inside the size of attribute '{}'", name));
      at += 4;
      const int32_t size = int32_t(uint32_t(b[0]) | uint32_t(b[1]) << 8 | uint32_t(b[2]) << 16 | uint32_t(b[3]) << 24);
      if (size < 0 || at + uint64_t(size) > file_bytes)
        fail(fmt::format("attribute '{}' ({}) claims {} bytes, but only {} remain in the {}-byte file", name, type,
                         size, file_bytes - std::min<uint64_t>(at, file_bytes), file_bytes));
      check_exr_attribute_value(f, name, type, size, max_name, fail);
      if (name == "dataWindow" && type == "box2i") check_exr_data_window(f, file_bytes, fail);
      f.seekg(size, std::ios::cur);
      at += uint64_t(size);
    }
    f.get(), ++at;  // the null byte that ends this header
    if (!multipart) break;
    if (part >= 1024) fail("more than 1024 parts");
  }
}

// libpng allocates what a chunk's length claims before it reads the chunk (1.7 GB for a damaged
// tEXt length, fuzz_image). Walk the chunks first: each is a big-endian uint32 length (at most
// 2^31 - 1, PNG's own limit), a 4-byte type, the data (skipped, not read) and a 4-byte CRC, up to
// IEND. Every length must fit in the bytes the file has; the message names the chunk. A file that
// ends at a chunk boundary before IEND is left to libpng, which reports it.
static void check_png_chunks(const std::string& path, std::istream& f, uint64_t file_bytes) {
  auto fail = [&](const std::string& reason) { throw Error(fmt::format("{}: damaged PNG file: {}", path, reason)); };
  f.clear();
  f.seekg(8);
  uint64_t at = 8;  // bytes of the file walked
  for (int chunk = 0; at < file_bytes; ++chunk) {
    unsigned char h[8];
    if (file_bytes - at < 8 || !f.read(reinterpret_cast<char*>(h), 8))
      fail(fmt::format("the file ends inside the header of chunk {} (byte {})", chunk, at));
    at += 8;
    const uint32_t length = uint32_t(h[0]) << 24 | uint32_t(h[1]) << 16 | uint32_t(h[2]) << 8 | uint32_t(h[3]);
    std::string type;
    for (int i = 4; i < 8; ++i) type += std::isalpha(h[i]) ? char(h[i]) : '?';
    if (length > 0x7fffffffu || uint64_t(length) + 4 > file_bytes - at)
      fail(fmt::format("chunk {} ('{}') claims {} bytes, but only {} remain in the {}-byte file", chunk, type, length,
                       file_bytes - at, file_bytes));
    if (type == "IEND") return;
    f.seekg(std::streamoff(length) + 4, std::ios::cur);
    at += uint64_t(length) + 4;
  }
}

// Design: the header is checked in full against what will be read before any pixel buffer is
// allocated (the buffer is at most 2^28 pixels x 3 floats, whatever the file claims), so an image
// OpenImageIO opens but spectrack would misread (a VDB as a stack of slices, a multi-part EXR, a
// deep or 2-channel image, a cropped data window) is refused by name, never guessed at. The
// checks (open_checked) are shared by read_image and FilmPieceRows, which reads a band of rows at
// a time.
namespace {

// Volumes are refused by their magic number (OIIO's openvdb reader would parse a damaged VDB
// before any check here), and EXR headers and PNG chunks are walked before a library reads them.
void check_magic(const std::string& path, const char* what, uint64_t file_bytes) {
  unsigned char magic[8] = {};
  std::ifstream f(path, std::ios::binary);
  f.read(reinterpret_cast<char*>(magic), 8);
  const bool vdb = magic[0] == 0x20 && magic[1] == 0x42 && magic[2] == 0x44 && magic[3] == 0x56;  // OPENVDB_MAGIC
  const bool nvdb = std::memcmp(magic, "NanoVDB", 7) == 0;
  if (vdb || nvdb)
    throw Error(fmt::format("{}: is a{} volume (a 3-D image to OpenImageIO's openvdb reader); {} must be a 2-D image",
                            path, vdb ? "n OpenVDB" : " NanoVDB", what));
  if (std::memcmp(magic, "\x76\x2f\x31\x01", 4) == 0) check_exr_header(path, f, file_bytes);
  if (std::memcmp(magic, "\x89PNG\r\n\x1a\n", 8) == 0) check_png_chunks(path, f, file_bytes);
}

// An environment map: the whole display window, and channels it can read without guessing.
void check_environment_spec(OpenedImage& o, bool cropped, bool rgb_named, const std::function<void(const std::string&)>& fail) {
  const OIIO::ImageSpec& spec = o.spec;
  const RgbImage& img = o.img;
  const int nc = spec.nchannels;
  if (cropped)
    fail(fmt::format("its data window ({}x{} pixels at {},{}) is not its {}x{} display window (a tile or a crop); "
                     "an environment map must cover the whole sphere",
                     img.width, img.height, img.window.x0, img.window.y0, img.window.full_width, img.window.full_height));
  if (nc == 1 && spec.alpha_channel != 0 && spec.z_channel != 0) o.gray = 0;
  else if (nc == 2 && spec.alpha_channel == 1) o.gray = 0;  // gray + alpha: the alpha is ignored
  else if (!rgb_named)
    fail(fmt::format("has {} channel(s) ({}); an environment map needs one gray channel, gray + alpha, or R, G, B "
                     "first (further channels are ignored)",
                     nc, channel_list(spec)));
}

// A merge input: spectrack's channels only, 32-bit float, its data window inside its display window.
void check_film_piece_spec(const OpenedImage& o, bool rgb_named, bool half_allowed,
                           const std::function<void(const std::string&)>& fail) {
  const OIIO::ImageSpec& spec = o.spec;
  const RgbImage& img = o.img;
  const int nc = spec.nchannels;
  const size_t max_pixels = size_t(1) << 28;
  if (img.format != "openexr")
    fail(half_allowed ? fmt::format("a {} image, not an EXR: only spectrack's EXR outputs are read here", img.format)
                      : fmt::format("a {} image cannot be merged: only spectrack's EXR outputs hold the float pixels "
                                    "and sample ranges a merge needs",
                                    img.format));
  // R, G, B first (OpenImageIO orders an EXR's R, G, B, A first), then film layers only
  bool layers_known = rgb_named && spec.channelnames.size() == size_t(nc);
  for (int c = 3; c < nc && layers_known; ++c) layers_known = film_layer_channel(spec.channelnames[c]);
  if (!layers_known)
    fail(fmt::format("has {} channel(s) ({}); spectrack's EXR outputs have R, G, B and its film layers only (A, AR, "
                     "AG, AB, environment.*, variance.*, emission.*, direct.*, indirect.*, albedo.*, depth.Z, collision.fraction)",
                     nc, channel_list(spec)));
  if (size_t(spec.width) * size_t(spec.height) * size_t(nc) > 3 * max_pixels)
    fail(fmt::format("{}x{} pixels of {} channels are more than a merge input can hold (3 * 2^28 values)", spec.width,
                     spec.height, nc));
  auto allowed = [&](const OIIO::TypeDesc& t) {
    return t == OIIO::TypeDesc::FLOAT || (half_allowed && t == OIIO::TypeDesc::HALF);
  };
  bool all_allowed = allowed(spec.format);
  for (auto& t : spec.channelformats) all_allowed = all_allowed && allowed(t);
  if (!all_allowed)
    fail(fmt::format("holds {} pixels; a merge takes 32-bit float EXRs only (a half-float file, --half, or a converted "
                     "one has lost the exact sums a merge needs)",
                     spec.format.c_str()));
  // OpenImageIO names it as --compression does, a DWA level after a colon ("dwaa:45")
  std::string compression = spec.get_string_attribute("compression");
  compression = compression.substr(0, compression.find(':'));
  if (!half_allowed && !exr_compression_keeps_floats(compression))
    fail(fmt::format("is compressed with {}, which changes float pixels: it has lost the exact sums a merge needs "
                     "(render pieces with a lossless --compression: zip, the default, zips, piz, rle or none)",
                     compression));
  if (img.window.x0 < 0 || img.window.y0 < 0 || int64_t(img.window.x0) + img.width > img.window.full_width ||
      int64_t(img.window.y0) + img.height > img.window.full_height)
    fail(fmt::format("its data window ({}x{} pixels at {},{}) leaves its {}x{} display window", img.width, img.height,
                     img.window.x0, img.window.y0, img.window.full_width, img.window.full_height));
}

}  // namespace

OpenedImage open_checked(const std::string& path, ImageUse use) {
  const bool env = use == ImageUse::kEnvironmentMap;
  const char* what = env ? "an environment map" : "a merge input";
  auto fail = [&](const std::string& reason) -> void { throw Error(path + ": " + reason); };
  const uint64_t file_bytes = check_input_file(path, "");  // a FIFO would block OpenImageIO, a device never end
  check_magic(path, what, file_bytes);
  OIIO::ImageSpec config;
  config.attribute("oiio:UnassociatedAlpha", 1);  // colours as stored, not multiplied by alpha
  OpenedImage o;
  o.in = OIIO::ImageInput::open(path, &config);
  if (!o.in) fail(fmt::format("cannot read image: {}", OIIO::geterror()));
  o.spec = o.in->spec();  // a copy: seek_subimage replaces in->spec()
  const OIIO::ImageSpec& spec = o.spec;
  RgbImage& img = o.img;
  img.format = o.in->format_name();
  const size_t max_pixels = size_t(1) << 28;
  if (spec.depth > 1 || spec.tile_depth > 1)
    fail(fmt::format("is a 3-D image ({}x{}x{} voxels, read by OpenImageIO's {} reader); {} must be a 2-D image",
                     spec.width, spec.height, spec.depth, img.format, what));
  if (spec.deep) fail(fmt::format("is a deep image (several samples per pixel); {} must be a flat image", what));
  if (o.in->seek_subimage(1, 0))
    fail(fmt::format("holds more than one subimage (a multi-part or multi-frame {} file); {} must be a single image",
                     img.format, what));
  if (!o.in->seek_subimage(0, 0)) fail(fmt::format("cannot read image: {}", o.in->geterror()));
  const int nc = spec.nchannels;
  if (spec.width <= 0 || spec.height <= 0 || nc <= 0 || size_t(spec.width) * size_t(spec.height) > max_pixels)
    fail(fmt::format("unsupported image size {}x{} with {} channels (at most 2^28 pixels)", spec.width, spec.height, nc));
  // A header can claim any size; the pixels a file of N bytes can hold are bounded by its codec's
  // best ratio (zip, RLE, DWA on a constant image: well under 4096 pixels a byte). A claim past that
  // is a damaged header, refused before its buffers are allocated (fuzz_image: a 65-byte HDR file
  // claimed 5 x 33 million pixels, 2 GB).
  const double claimed = double(spec.width) * double(spec.height);
  if (claimed > double(file_bytes) * kMaxPixelsPerFileByte + double(1 << 20))
    fail(fmt::format("its header claims {}x{} pixels, more than a file of {} bytes can hold (damaged or truncated)",
                     spec.width, spec.height, file_bytes));
  if (spec.tile_width > 0 && size_t(spec.tile_width) * size_t(std::max(spec.tile_height, 1)) > max_pixels)
    fail(fmt::format("tiles of {}x{} pixels are more than the 2^28 pixels an image can have", spec.tile_width,
                     spec.tile_height));
  img.width = spec.width;
  img.height = spec.height;
  img.window.x0 = spec.x - spec.full_x;
  img.window.y0 = spec.y - spec.full_y;
  img.window.full_width = spec.full_width > 0 ? spec.full_width : spec.width;
  img.window.full_height = spec.full_height > 0 ? spec.full_height : spec.height;
  const bool cropped = img.window.x0 != 0 || img.window.y0 != 0 || img.window.full_width != img.width ||
                       img.window.full_height != img.height;
  auto base = [&](int c) { return c < int(spec.channelnames.size()) ? channel_base(spec.channelnames[c]) : ""; };
  const bool rgb_named = nc >= 3 && base(0) == "R" && base(1) == "G" && base(2) == "B";
  if (env) check_environment_spec(o, cropped, rgb_named, fail);
  else check_film_piece_spec(o, rgb_named, use == ImageUse::kSpectrackExr, fail);
  if (!env && nc > 3) img.extra_names.assign(spec.channelnames.begin() + 3, spec.channelnames.begin() + nc);
  for (const auto& a : spec.extra_attribs) {
    std::string n = a.name().string();
    if (n.rfind("spectrack:", 0) != 0) continue;
    std::string k = n.substr(10);
    if (a.type() == OIIO::TypeDesc::INT) img.meta[k] = a.get_int();
    else if (a.type() == OIIO::TypeDesc::FLOAT) img.meta[k] = a.get_float();
    else img.meta[k] = a.get_string();
  }
  return o;
}

void check_finite(const std::string& path, const RgbImage& img, int row0, const float* rgb, const float* extra,
                  size_t npix) {
  const size_t ne = img.extra_names.size();
  for (size_t i = 0; i < npix * ne; ++i)
    if (!std::isfinite(extra[i]))
      throw Error(fmt::format("{}: channel {} holds a non-finite value ({}); spectrack writes finite pixels only", path,
                              img.extra_names[i % ne], extra[i]));
  const size_t first = size_t(row0) * size_t(img.width);
  for (size_t i = 0; i < npix * 3; ++i)
    if (!std::isfinite(rgb[i]))
      throw Error(fmt::format("{}: pixel {},{} holds a non-finite value ({}); spectrack writes finite pixels only", path,
                              img.window.x0 + int((first + i / 3) % size_t(img.width)),
                              img.window.y0 + int((first + i / 3) / size_t(img.width)), rgb[i]));
}

namespace {

// 8-bit PNG and JPEG files hold sRGB-encoded values; radiance is linear.
void decode_colour_space(const OIIO::ImageSpec& spec, std::vector<float>& rgb, const std::function<void(const std::string&)>& fail) {
  std::string cs = spec.get_string_attribute("oiio:ColorSpace");
  const std::string lower = to_lower(cs);
  if (lower == "srgb") {
    for (float& v : rgb) v = srgb_decode(v);
  } else if (lower.rfind("gammacorrected", 0) == 0) {
    float gamma = std::strtof(cs.c_str() + 14, nullptr);
    if (!(gamma > 0.0f && gamma < 10.0f)) fail(fmt::format("unsupported colour space {}", cs));
    for (float& v : rgb) v = v > 0.0f ? std::pow(v, gamma) : 0.0f;
  }
}

}  // namespace

RgbImage read_image(const std::string& path, ImageUse use, const std::function<void(int, int)>& before_pixels) {
  const bool env = use == ImageUse::kEnvironmentMap;
  auto fail = [&](const std::string& reason) -> void { throw Error(path + ": " + reason); };
  OpenedImage o = open_checked(path, use);
  RgbImage& img = o.img;
  if (before_pixels) before_pixels(img.width, img.height);
  const int gray = o.gray;
  const size_t n = size_t(img.width) * size_t(img.height);
  const int nread = gray >= 0 ? 1 : (env ? 3 : o.spec.nchannels);  // a film piece: every channel (its layers)
  img.rgb.resize(n * 3);
  std::vector<float> g;
  if (gray >= 0 || nread > 3) g.resize(n * size_t(nread));
  float* dst = !g.empty() ? g.data() : img.rgb.data();
  if (!o.in->read_image(0, 0, gray >= 0 ? gray : 0, (gray >= 0 ? gray : 0) + nread, OIIO::TypeDesc::FLOAT, dst))
    fail(fmt::format("cannot read pixels: {}", o.in->geterror()));
  if (gray < 0 && nread > 3) {
    const size_t ne = size_t(nread) - 3;
    img.extra.resize(n * ne);
    for (size_t i = 0; i < n; ++i) {
      for (int c = 0; c < 3; ++c) img.rgb[i * 3 + c] = g[i * nread + c];
      for (size_t c = 0; c < ne; ++c) img.extra[i * ne + c] = g[i * nread + 3 + c];
    }
  }
  if (gray >= 0)
    for (size_t i = 0; i < n; ++i) img.rgb[i * 3] = img.rgb[i * 3 + 1] = img.rgb[i * 3 + 2] = g[i];
  if (env) decode_colour_space(o.spec, img.rgb, fail);
  else check_finite(path, img, 0, img.rgb.data(), img.extra.data(), n);
  o.in->close();
  return img;
}

}  // namespace spectrack
