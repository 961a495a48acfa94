// image_rows.h: images read and written a band of rows at a time, so that a merge's memory is
// bounded by a band, not by the size or number of its inputs.
//
// Design: FilmPieceRows opens a merge input with read_image's checks (ImageUse::kFilmPiece) and
// reads any band of rows of its data window, every channel, checked finite as it is read (a
// tiled file in whole rows of tiles, so a band costs up to a tile's height more).
// ImageRowWriter writes rows in order to a temporary file beside its path (same folder, so the
// rename is atomic) and renames it over the path only in finish(): an error part-way (a damaged
// input found in its last rows) leaves no half-written image and keeps an older file intact.
#pragma once
#include <memory>
#include <string>
#include <vector>

#include "image/image.h"

namespace spectrack {

class FilmPieceRows {
 public:
  explicit FilmPieceRows(const std::string& path);  // throws Error as read_image does
  ~FilmPieceRows();
  // Everything but the pixels (rgb, extra empty): size, window, extra_names, metadata.
  const RgbImage& header() const;
  // Rows y0..y1-1 of the data window (0 = its first row): R, G, B to rgb, the layers
  // (header().extra_names) to extra, pixel-major; throws Error naming a non-finite value.
  void read(int y0, int y1, std::vector<float>* rgb, std::vector<float>* extra);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

class ImageRowWriter {
 public:
  // An EXR (float or half channels `names`, exr's compression) or, for a .png path, an 8-bit sRGB
  // image of R, G, B (`names` must be R, G, B), with `meta` as spectrack:* metadata.
  ImageRowWriter(const std::string& path, int width, int height, const std::vector<std::string>& names,
                 const Metadata& meta, const PixelWindow& window, const ExrOptions& exr = {});
  ~ImageRowWriter();  // without finish(): the temporary file is removed
  // The next rows, y0 (0 = the first) .. y1-1, names.size() floats per pixel, pixel-major.
  void write(int y0, int y1, const std::vector<float>& px);
  // Closes the file and renames it to the path; throws Error on failure.
  void finish();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace spectrack
