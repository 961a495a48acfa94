// image.h: image output (image_write.cpp) and input (image.cpp) through OpenImageIO. EXR gets
// linear float RGB plus the render's metadata as string/int/float attributes; PNG gets an 8-bit
// sRGB preview (clamped). The format follows the file extension; anything else is refused before
// rendering. An image is written to a temporary file and renamed into place once every write
// succeeded (util/output_file.h): a failed write leaves nothing under the final name.
#pragma once
#include <functional>
#include <map>
#include <string>
#include <variant>
#include <vector>

#include "util/error.h"

namespace spectrack {

using MetaValue = std::variant<std::string, int, float>;
using Metadata = std::map<std::string, MetaValue>;

// Throws Error unless `path` is not an existing folder, device or FIFO, has a writable extension
// (.exr, .png) and check_writable_file holds.
void check_output_path(const std::string& path);
// Throws Error unless a file can be created at `path` (check_creatable_file of util/output_file.h).
void check_writable_file(const std::string& path);
// Where an image sits in a larger film: an EXR of a pixel window (a tile) keeps the film as its
// display window and the tile as its data window. full_width == 0: the image is the whole film.
struct PixelWindow {
  int full_width = 0, full_height = 0;
  int x0 = 0, y0 = 0;
};

// How an EXR is stored: 16-bit half or 32-bit float channels, and the OpenEXR compression
// (exr_compressions() of scene.h).
struct ExrOptions {
  bool half = false;
  std::string compression = "zip";
};

// Writes width x height linear RGB floats (row 0 at the top). PNG previews hold the pixels only.
// Both writers throw Error "<path>: cannot write: <reason>" when any write fails.
void write_image(const std::string& path, int width, int height, const std::vector<float>& rgb, const Metadata& meta,
                 const PixelWindow& window = {}, const ExrOptions& exr = {});
// Writes an EXR with the named channels (pixel-major: px[pixel * names.size() + c]); a channel
// named "A" is marked as the alpha channel.
void write_exr_channels(const std::string& path, int width, int height, const std::vector<std::string>& names,
                        const std::vector<float>& px, const Metadata& meta, const PixelWindow& window,
                        const ExrOptions& exr);

struct RgbImage {
  int width = 0, height = 0;    // the pixels held (EXR data window)
  PixelWindow window;           // their place in the display window (full size always set)
  std::string format;           // OIIO's format name: "openexr", "png", ...
  std::vector<float> rgb;  // linear, row 0 at the top
  // kFilmPiece: the channels besides R, G, B (film layers, docs/aov.md), pixel-major
  std::vector<std::string> extra_names;
  std::vector<float> extra;
  Metadata meta;
};
// What an image is read for; the checks and conversions differ (image.cpp, docs/limits.md).
enum class ImageUse {
  kEnvironmentMap,  // 1 channel (gray, replicated), gray + alpha, or R, G, B (+ more, ignored);
                    // sRGB / gamma-encoded files are decoded to linear; the whole display window
  kFilmPiece,       // a spectrack EXR: float R, G, B and spectrack's layers only (film_layer_channel), finite,
                    // its data window inside the display window
  kSpectrackExr,    // the same, half floats and lossy compressions allowed (--half, write(half=True), dwaa):
                    // a file read for its channels (the Python module's read_exr), not merged
};
// Reads one 2-D image (subimage 0, MIP level 0) as linear float RGB. Throws Error naming the
// file and the reason for anything it cannot read as `use` says: not a regular file, volumes
// (depth > 1), deep images, several subimages, no pixels or more than 2^28, channels it would
// have to guess, tiles bigger than that bound.
// `before_pixels`, when given, sees the size (width, height) once the header is checked and before
// any pixel memory is allocated; it may throw to refuse the image (a memory estimate).
RgbImage read_image(const std::string& path, ImageUse use = ImageUse::kEnvironmentMap,
                    const std::function<void(int, int)>& before_pixels = {});
// The channel names a film piece may hold besides R, G, B (the EXR layers of docs/aov.md).
bool film_layer_channel(const std::string& name);

}  // namespace spectrack
