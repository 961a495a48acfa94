// image_open.h: what image.cpp shares with image_rows.cpp (not for other callers): an image
// opened with its header checked, the finiteness check of a film piece's pixels, and the EXR
// header and sRGB encoding of the writers.
#pragma once
#include <OpenImageIO/imageio.h>

#include <memory>
#include <string>

#include "image/image.h"

namespace spectrack {

struct OpenedImage {
  std::unique_ptr<OIIO::ImageInput> in;
  OIIO::ImageSpec spec;
  RgbImage img;   // everything but the pixels (rgb and extra empty; extra_names, meta set)
  int gray = -1;  // an environment map: the channel replicated to RGB, or -1 for R, G, B
};

// Opens `path` and checks its header for `use` (read_image's refusals); no pixel is read yet.
OpenedImage open_checked(const std::string& path, ImageUse use);
// A film piece holds finite values only: the first non-finite value of `npix` pixels starting at
// row `row0` of the data window is named (the layers' before the colour's); throws Error.
void check_finite(const std::string& path, const RgbImage& img, int row0, const float* rgb, const float* extra,
                  size_t npix);
// The EXR header's metadata (spectrack:*), compression and windows.
void set_exr_spec(OIIO::ImageSpec& spec, const Metadata& meta, const PixelWindow& window, const ExrOptions& exr);
// Linear to sRGB-encoded, clamped to [0, 1].
float srgb_encode(float v);

}  // namespace spectrack
