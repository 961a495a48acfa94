// merge_files.cpp: see merge_files.h.
#include "film/merge_files.h"

#include <fmt/format.h>

#include <algorithm>
#include <memory>

#include "image/image_rows.h"

namespace spectrack {

MergeInput read_merge_header(const std::string& path) {
  FilmPieceRows rows(path);
  MergeInput in;
  in.piece = piece_from_header(path, rows.header());
  in.extra_names = rows.header().extra_names;
  in.meta = rows.header().meta;
  return in;
}

namespace {

// Rows per band: band_bytes over what one output row takes (its sums, an input's row read and
// decoded, the output row), in whole EXR chunks of 16 rows where more than 16 fit; at least one.
int band_rows(const FilmPiece& layout, size_t nc_in, size_t band_bytes) {
  const size_t ns = 3 + aov_sum_channels(layout.id.aovs).size();
  const size_t per_pixel = 2 * ns * sizeof(double) + 3 * nc_in * sizeof(float) + ns * 2 * sizeof(float) + 4;
  const size_t per_row = std::max<size_t>(1, size_t(layout.width) * per_pixel);
  size_t rows = std::max<size_t>(1, band_bytes / per_row);
  if (rows > 16) rows -= rows % 16;
  return int(std::min<size_t>(rows, size_t(layout.height)));
}

// Adds rows gy0..gy1-1 (film rows) of `in` into `band` (whose rows start at band.y0).
void add_rows(const MergeInput& in, FilmPiece& band, int gy0, int gy1, std::vector<float>& rgb,
              std::vector<float>& extra, std::vector<double>& sum, std::vector<double>& aov) {
  const FilmPiece& p = in.piece;
  FilmPieceRows rows(p.source);
  const RgbImage& h = rows.header();
  const FilmPiece now = piece_from_header(p.source, h);
  if (now.width != p.width || now.height != p.height || now.x0 != p.x0 || now.y0 != p.y0 ||
      now.id.aovs != p.id.aovs || now.id.scene_hash != p.id.scene_hash ||
      format_ranges(now.ranges) != format_ranges(p.ranges) || h.extra_names != in.extra_names)
    throw Error(fmt::format("{}: changed while it was being merged", p.source));
  rows.read(gy0 - p.y0, gy1 - p.y0, &rgb, &extra);
  const size_t npix = size_t(gy1 - gy0) * size_t(p.width), na = aov_sum_channels(p.id.aovs).size();
  sum.resize(npix * 3);
  aov.resize(npix * na);
  PieceDecoder(p, in.extra_names).decode(rgb.data(), extra.data(), npix, sum.data(), aov.data());
  for (auto [from, to, nc] : {std::tuple{&sum, &band.sum, size_t(3)}, std::tuple{&aov, &band.aov_sum, na}})
    for (int y = 0; y < gy1 - gy0 && nc > 0; ++y) {
      const double* src = &(*from)[size_t(y) * p.width * nc];
      double* dst = &(*to)[(size_t(gy0 - band.y0 + y) * band.width + (p.x0 - band.x0)) * nc];
      for (size_t i = 0; i < size_t(p.width) * nc; ++i) dst[i] += src[i];
    }
}

}  // namespace

void write_merged(const std::vector<MergeInput>& inputs, const FilmPiece& layout, const std::string& output,
                  const std::string& preview, const Metadata& meta, const ExrOptions& exr, size_t band_bytes) {
  Metadata m = meta;
  for (auto& [k, v] : piece_metadata(layout)) m[k] = v;
  const PixelWindow window = piece_window(layout);
  FilmPiece band = layout;  // its sums: one band of rows
  band.height = 0;
  std::vector<float> px;
  const std::vector<std::string> names = piece_exr_channels(band, &px);
  ImageRowWriter exr_out(output, layout.width, layout.height, names, m, window, exr);
  std::unique_ptr<ImageRowWriter> png_out;
  if (!preview.empty())
    png_out = std::make_unique<ImageRowWriter>(preview, layout.width, layout.height, std::vector<std::string>{"R", "G", "B"},
                                               m, window);
  const int rows = band_rows(layout, 3 + (inputs.empty() ? 0 : inputs[0].extra_names.size()), band_bytes);
  const size_t na = aov_sum_channels(layout.id.aovs).size();
  std::vector<float> rgb, extra;
  std::vector<double> sum, aov;
  for (int r0 = 0; r0 < layout.height; r0 += rows) {
    const int r1 = std::min(layout.height, r0 + rows);
    band.y0 = layout.y0 + r0;
    band.height = r1 - r0;
    band.sum.assign(size_t(band.width) * band.height * 3, 0.0);
    band.aov_sum.assign(size_t(band.width) * band.height * na, 0.0);
    for (const MergeInput& in : inputs) {
      const int gy0 = std::max(band.y0, in.piece.y0), gy1 = std::min(band.y0 + band.height, in.piece.y0 + in.piece.height);
      if (gy0 < gy1) add_rows(in, band, gy0, gy1, rgb, extra, sum, aov);
    }
    piece_exr_channels(band, &px);
    exr_out.write(r0, r1, px);
    if (png_out) png_out->write(r0, r1, piece_beauty(band));
  }
  exr_out.finish();
  if (png_out) png_out->finish();
}

}  // namespace spectrack
