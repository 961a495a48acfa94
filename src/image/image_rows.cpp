// image_rows.cpp: see image_rows.h. The EXR and PNG headers are made as write_exr_channels and
// write_image make them, and the pixels converted the same way, so a file written in bands has
// the same pixels and metadata as one written whole.
#include "image/image_rows.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "image/image_open.h"
#include "image/output_proxy.h"
#include "util/output_file.h"
#include "util/strings.h"

namespace spectrack {

struct FilmPieceRows::Impl {
  std::string path;
  OpenedImage o;
  std::vector<float> scratch;  // one band, every channel
};

FilmPieceRows::FilmPieceRows(const std::string& path) : impl_(new Impl) {
  impl_->path = path;
  impl_->o = open_checked(path, ImageUse::kFilmPiece);
}

FilmPieceRows::~FilmPieceRows() = default;

const RgbImage& FilmPieceRows::header() const { return impl_->o.img; }

void FilmPieceRows::read(int y0, int y1, std::vector<float>* rgb, std::vector<float>* extra) {
  OpenedImage& o = impl_->o;
  const RgbImage& img = o.img;
  if (y0 < 0 || y1 > img.height || y0 >= y1)
    throw Error(fmt::format("{}: internal: rows {}..{} of {}", impl_->path, y0, y1, img.height));
  const size_t nc = size_t(o.spec.nchannels), ne = nc - 3, npix = size_t(y1 - y0) * size_t(img.width);
  // a tiled file (spectrack writes scanlines; a converted file may be tiled) is read in whole
  // rows of tiles, from the data window's origin, to its last row at most
  const int th = o.spec.tile_width > 0 ? std::max(1, o.spec.tile_height) : 1;
  const int ya = y0 - y0 % th, yb = std::min(img.height, y1 + (th - y1 % th) % th);
  impl_->scratch.resize(size_t(yb - ya) * size_t(img.width) * nc);
  const bool ok = o.spec.tile_width > 0
                      ? o.in->read_tiles(0, 0, o.spec.x, o.spec.x + img.width, o.spec.y + ya, o.spec.y + yb, o.spec.z,
                                         o.spec.z + 1, 0, int(nc), OIIO::TypeDesc::FLOAT, impl_->scratch.data())
                      : o.in->read_scanlines(0, 0, o.spec.y + y0, o.spec.y + y1, 0, 0, int(nc), OIIO::TypeDesc::FLOAT,
                                             impl_->scratch.data());
  if (!ok) throw Error(fmt::format("{}: cannot read pixels: {}", impl_->path, o.in->geterror()));
  rgb->resize(npix * 3);
  extra->resize(npix * ne);
  const float* g = impl_->scratch.data() + size_t(y0 - ya) * size_t(img.width) * nc;
  for (size_t i = 0; i < npix; ++i) {
    for (size_t c = 0; c < 3; ++c) (*rgb)[i * 3 + c] = g[i * nc + c];
    for (size_t c = 0; c < ne; ++c) (*extra)[i * ne + c] = g[i * nc + 3 + c];
  }
  check_finite(impl_->path, img, y0, rgb->data(), extra->data(), npix);
}

// Members are destroyed in reverse: the writer first, then the proxy, then the file, which
// removes its temporary file unless committed.
struct ImageRowWriter::Impl {
  std::string path;
  std::unique_ptr<OutputFile> file;
  std::unique_ptr<OutputProxy> proxy;
  std::unique_ptr<OIIO::ImageOutput> out;
  OIIO::ImageSpec spec;
  bool png = false, finished = false;
  int next_row = 0;
  std::vector<unsigned char> bytes;  // a PNG band
  [[noreturn]] void fail();
};

ImageRowWriter::ImageRowWriter(const std::string& path, int width, int height, const std::vector<std::string>& names,
                               const Metadata& meta, const PixelWindow& window, const ExrOptions& exr)
    : impl_(new Impl) {
  Impl& w = *impl_;
  check_output_path(path);
  std::string ext = lower_extension(path);
  w.png = ext == ".png";
  if (w.png && names != std::vector<std::string>{"R", "G", "B"})
    throw Error(fmt::format("{}: internal: a PNG holds R, G, B only", path));
  w.path = path;
  w.file = std::make_unique<OutputFile>(path);
  w.proxy = std::make_unique<OutputProxy>(*w.file);
  w.out = OIIO::ImageOutput::create(path, w.proxy.get());  // the format of the path's extension
  if (!w.out) throw Error(fmt::format("{}: cannot create image writer: {}", path, OIIO::geterror()));
  if (w.png) {
    w.spec = OIIO::ImageSpec(width, height, 3, OIIO::TypeDesc::UINT8);
    for (auto& [k, v] : meta) {
      std::string key = "spectrack:" + k;
      if (auto s = std::get_if<std::string>(&v)) w.spec.attribute(key, *s);
      else if (auto i = std::get_if<int>(&v)) w.spec.attribute(key, *i);
      else if (auto f = std::get_if<float>(&v)) w.spec.attribute(key, *f);
    }
  } else {
    w.spec = OIIO::ImageSpec(width, height, int(names.size()), exr.half ? OIIO::TypeDesc::HALF : OIIO::TypeDesc::FLOAT);
    w.spec.channelnames = names;
    w.spec.alpha_channel = -1;
    for (size_t c = 0; c < names.size(); ++c)
      if (names[c] == "A") w.spec.alpha_channel = int(c);
    set_exr_spec(w.spec, meta, window, exr);
  }
  if (!w.out->open(path, w.spec)) w.fail();
}

ImageRowWriter::~ImageRowWriter() = default;  // unfinished: the OutputFile removes its temporary file

// Raises the first failure: the OutputFile's own (a write's errno) before the writer's message.
void ImageRowWriter::Impl::fail() {
  file->fail(out->geterror());
  out.reset();
  file->commit();  // throws "<path>: cannot write: <reason>" and removes the temporary file
  throw Error(fmt::format("{}: cannot write", path));  // not reached: commit throws on a failed file
}

void ImageRowWriter::write(int y0, int y1, const std::vector<float>& px) {
  Impl& w = *impl_;
  const size_t nc = size_t(w.spec.nchannels), npix = size_t(y1 - y0) * size_t(w.spec.width);
  if (y0 != w.next_row || y1 > w.spec.height || y1 <= y0 || px.size() != npix * nc)
    throw Error(fmt::format("{}: internal: rows {}..{} written out of order", w.path, y0, y1));
  bool ok = false;
  if (w.png) {
    w.bytes.resize(px.size());
    for (size_t i = 0; i < px.size(); ++i) w.bytes[i] = (unsigned char)std::lround(srgb_encode(px[i]) * 255.0f);
    ok = w.out->write_scanlines(w.spec.y + y0, w.spec.y + y1, 0, OIIO::TypeDesc::UINT8, w.bytes.data());
  } else {
    ok = w.out->write_scanlines(w.spec.y + y0, w.spec.y + y1, 0, OIIO::TypeDesc::FLOAT, px.data());
  }
  if (!ok || w.file->failed()) w.fail();
  w.next_row = y1;
}

void ImageRowWriter::finish() {
  Impl& w = *impl_;
  if (w.next_row != w.spec.height)
    throw Error(fmt::format("{}: internal: {} of {} rows written", w.path, w.next_row, w.spec.height));
  if (!w.out->close() || w.out->has_error() || w.file->failed()) w.fail();
  w.out.reset();
  if (w.file->size() == 0) w.file->fail("the image writer wrote nothing through spectrack's output file");
  w.file->commit();
  w.finished = true;
}

}  // namespace spectrack
