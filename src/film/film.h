// film.h: a render as pieces that combine exactly: sample-range shards, pixel tiles, devices and
// MPI ranks.
//
// Design: a FilmPiece is a pixel window of the full film, the set of sample indices it holds
// (disjoint half-open ranges of the full per-pixel sequence) and, per pixel, the sum of those
// samples in double. The counter-based RNG keys every path by (pixel, sample, channel), so pieces
// with disjoint sample ranges are disjoint parts of the one long render, and adding their sums
// (merge_pieces) gives that render's image to float rounding. A piece also carries the identity
// of the render it belongs to (scene hash, film size, seed, tracker, scheme, version); merging
// refuses pieces of different renders, sample ranges that overlap on any pixel, pixels of the
// bounding box that no piece covers, and pixels that would end with different sample sets.
// On disk a piece is an EXR: the mean (sum / samples) as pixels, the tile as the data window of
// the full film's display window, and the identity and ranges as spectrack:* metadata. Film
// layers (alpha, environment, variance: docs/aov.md) are sums too (variance as second moments),
// merged the same way; pieces with different layers are refused.
#pragma once
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "image/image.h"
#include "integrator/renderer.h"
#include "scene/scene.h"

namespace spectrack {

struct SampleRange {
  int64_t begin = 0, end = 0;  // samples begin .. end - 1
};
// "0:4,8:12"; parse_ranges throws Error naming `what` on malformed text.
std::string format_ranges(const std::vector<SampleRange>& ranges);
std::vector<SampleRange> parse_ranges(const std::string& text, const std::string& what);
// Sorted, with touching ranges joined; empty ranges dropped (overlaps are the caller's check).
std::vector<SampleRange> join_ranges(std::vector<SampleRange> ranges);
int64_t count_samples(const std::vector<SampleRange>& ranges);

// The identity text of the majorant choices (RenderSettings::majorant_*; 0 and none: automatic;
// blocks of 0 and 1 are one level alike). The choices as given: a cell given as the number the
// automatic choice would take is recorded as another choice (merge refuses such pieces, safely).
std::string majorant_identity(int cell, int block, const std::optional<double>& step_cost);

// What pieces of one render share.
struct RenderIdentity {
  std::string scene_hash;
  int full_width = 0, full_height = 0;
  int64_t seed = 0;
  std::string tracker, scheme, version;
  std::string absorption = "event";  // st_absorption name (pieces written before the option: event)
  std::string light_sampling = "all";  // st_light_sampling name (pieces written before the option: all)
  std::string transmittance = "ratio";  // st_transmittance_mode name (pieces written before the option: ratio)
  std::string lookup = "trilinear";  // st_lookup_mode name (pieces written before the option: trilinear)
  std::string color = "rgb";         // st_film_color name (pieces written before spectral mode: rgb)
  std::string wavelength_sampling;  // spectral mode: st_wavelength_sampling name; empty in rgb mode (and pieces written before it)
  std::string guided = "off";  // volume path guiding as run (auto resolved): on or off (pieces written before it: off)
  std::string guide_splitting = "off";  // guided roulette and splitting: on or off (off without guiding, and in pieces written before it)
  std::string equiangular = "off";  // equi-angular sampling as requested: off, on or auto (pieces written before it: off)
  uint32_t aovs = 0;  // the film layers (ST_AOV_BIT bits; pieces written before them: none)
  // the shutter, "open:close" in seconds, and the samples the paths' times are stratified over
  // ("0:0.02/64"); empty: no shutter (pieces written before it: none)
  std::string shutter;
  std::string frame;  // the frame number of a sequence's frame (--frames); empty: not a sequence
  // A sequence frame's camera as framed over the sequence's frames (--frames with a camera that
  // frames the media, whose framing depends on the frame range); empty otherwise
  std::string camera;
  // The choices that change which random numbers a sample draws or what a ray-marching sample
  // weighs (RenderSettings): pieces written before they were recorded hold the defaults (none for
  // ray marching: an older ray-marching piece matches no newer one)
  std::string iteration_budget = std::to_string(kDefaultIterationBudget);
  std::string majorant = majorant_identity(0, kDefaultMajorantBlock, std::nullopt);
  std::string ray_marching;  // with ray-marching transmittance: its spacings; empty otherwise
};

// A SHA-1 of the scene as it shapes the image: the scene file's JSON (keys sorted, whitespace
// dropped; without film.output, film.spp, the film's storage and layer fields (alpha, aovs, half,
// compression: the layers are compared on their own), the render fields that are recorded on their own:
// seed, tracker, spectral_scheme, absorption, light_sampling, transmittance, lookup, color,
// noise_target, equiangular, the run control render.time_limit (no image changes with it), and the
// names of referenced files) and the contents of every
// file it references (VDB files, environment maps), so a scene moved to another folder or
// machine keeps its hash.
std::string scene_hash(const SceneDesc& scene);
// The same of a scene parsed from `json_text` (parse_scene: a scene made in memory).
std::string scene_hash(const SceneDesc& scene, const std::string& json_text);
// The identity of a render with these settings, without scene_hash: hashing reads every
// referenced file, so the caller computes it where it does not delay the render (the CLI overlaps
// it with rendering, on the rank that writes).
RenderIdentity render_identity(const RenderSettings& settings);

// The choices a render records by name, in one list: EXR metadata spectrack:<key> (film_io.cpp
// writes and reads them), the statistics JSON's <key> (api/render_stats.cpp), merge's comparison
// (check_one_render names `what`) and the film state's key (film_watch.h film_state_key).
// `required`: every piece has it; the others may be missing from pieces written before the
// option, which then hold RenderIdentity's default.
struct RecordedChoice {
  const char* key;
  std::string RenderIdentity::*field;
  const char* what;
  bool required;
  bool only_when_set = false;  // written only where not empty (empty: "none" in messages)
};
const std::vector<RecordedChoice>& recorded_choices();

struct FilmPiece {
  std::string source;  // the file (or device, or rank) it came from, for messages
  RenderIdentity id;
  int x0 = 0, y0 = 0, width = 0, height = 0;
  std::vector<SampleRange> ranges;  // sorted, disjoint, joined
  std::vector<double> sum;          // width * height * 3: R, G, B (with alpha the transparent film's, renderer.h)
  std::vector<double> aov_sum;      // width * height * aov_sum_channels(id.aovs).size() (renderer.h)
  bool interrupted = false;
  // Adaptive sampling (integrator/adaptive.h): the samples each pixel took (EXR channel "samples");
  // the sums are then weighted estimates times samples(). Empty otherwise.
  std::vector<float> pixel_samples;
  // The denoised beauty (--denoise, image/denoise.h), 3 per pixel: EXR channels denoised.R/G/B; empty
  // otherwise. Not a sum: a merge drops it.
  std::vector<float> denoised;
  int64_t samples() const { return count_samples(ranges); }
  // Mean per pixel (0 where no sample).
  std::vector<float> mean() const;
};

// A piece of window w that holds no sample yet (zero sums): what a device or an MPI rank that
// rendered nothing contributes.
FilmPiece empty_piece(const RenderIdentity& id, const FilmWindow& w, const std::string& source);
FilmPiece piece_from_result(const RenderResult& r, const RenderIdentity& id, const std::string& source);
// Combines pieces into one over their bounding box; throws Error (naming the sources) as above.
FilmPiece merge_pieces(const std::vector<FilmPiece>& pieces);
// The refusal of an adaptive render (its 'samples' layer) as a merge input, named by `source`.
UsageError adaptive_merge_error(const std::string& source);
// merge_pieces' checks and result without the sums: the pieces may be headers (no sums); the
// result has the window, ranges, identity and interrupted flag of the merge (film/merge_files.h
// adds the sums a band of rows at a time).
FilmPiece plan_merge(const std::vector<FilmPiece>& pieces);

// spp, spp_ranges (and spp_begin / spp_end when contiguous), seed, tracker, scheme, version,
// scene_hash, pixel_bounds, full_resolution, interrupted.
Metadata piece_metadata(const FilmPiece& p);
// An EXR gets the layers of docs/aov.md: R, G, B (with alpha: transparent, premultiplied), A, AR,
// AG, AB, environment.R/G/B, variance.R/G/B; `exr` says half or float and the compression. A PNG
// gets the whole beauty (a transparent film's environment added back; no layers).
void write_piece(const std::string& path, const FilmPiece& p, const Metadata& extra, const ExrOptions& exr = {});
// Reads a piece written by write_piece; throws Error for PNGs and images without the metadata.
// `meta`, when given, gets the file's other spectrack:* metadata (device, render_seconds, ...).
// An adaptive render's EXR (its 'samples' layer) is refused as a merge input (adaptive_merge_error)
// unless `keep_adaptive`: then its per-pixel samples come back in pixel_samples (a piece that
// merge_pieces still refuses). The denoised layer, when whole, comes back in `denoised`.
FilmPiece read_piece(const std::string& path, Metadata* meta = nullptr, bool keep_adaptive = false);

// The parts of write_piece and read_piece, for a merge that streams rows (film/film_io.cpp):
// the EXR channels of p's pixels (names returned, values pixel-major in px), the beauty a PNG
// gets, and p's place in the film.
std::vector<std::string> piece_exr_channels(const FilmPiece& p, std::vector<float>* px);
std::vector<float> piece_beauty(const FilmPiece& p);
PixelWindow piece_window(const FilmPiece& p);
// The piece a file header describes (identity, window, ranges, layers; no sums): the refusals of
// read_piece that need no pixel, spp, spp_begin and spp_end checked against spp_ranges.
FilmPiece piece_from_header(const std::string& path, const RgbImage& header, bool keep_adaptive = false);
// Turns a piece file's pixels (R, G, B and the layers `extra_names`, as read) back into sums.
class PieceDecoder {
 public:
  PieceDecoder(const FilmPiece& header, const std::vector<std::string>& extra_names);
  // npix pixels: rgb 3 per pixel, extra extra_names.size() per pixel; sum 3 and aov_sum
  // aov_sum_channels(aovs).size() per pixel.
  void decode(const float* rgb, const float* extra, size_t npix, double* sum, double* aov_sum) const;

 private:
  // each sum's columns in the file: the channel itself, or for a second moment its variance.*
  // channel and (alpha: transparent R, G, B) its environment.* one
  struct Source {
    size_t col = 0;
    int moment_of = -1;  // second moments: the beauty channel 0..2
    size_t env_col = 0;
    bool per_collision = false;  // albedo, depth: a mean over the collided samples (collision.fraction of them)
    size_t ratio_of = 0;         // shadow: a ratio, the sum index of its denominator (unshadowed); 0: none
  };
  double n_;
  bool alpha_;
  size_t ne_;
  std::vector<Source> src_;
  size_t hits_col_ = 0;
};

}  // namespace spectrack
