// film_io.cpp: film pieces on disk (see film.h): an EXR holds each pixel's mean (sum / samples)
// and the film layers of docs/aov.md, with the identity and sample ranges as spectrack:*
// metadata; reading one turns the means back into sums. Both directions work per pixel
// (piece_exr_channels, PieceDecoder), so that a merge can stream a band of rows at a time
// (film/merge_files.h) with the very operations of a whole-image read and write.
#include "film/film.h"
#include "image/extra_channels.h"
#include "util/strings.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <limits>
#include <stdexcept>

namespace spectrack {

// An int where it fits, else the decimal text (readers take both).
static MetaValue int_or_text(int64_t v) {
  if (v >= std::numeric_limits<int>::min() && v <= std::numeric_limits<int>::max()) return int(v);
  return std::to_string(v);
}

Metadata piece_metadata(const FilmPiece& p) {
  Metadata m;
  m["spp"] = int_or_text(p.samples());
  m["spp_ranges"] = format_ranges(p.ranges);
  if (p.ranges.size() == 1) {
    m["spp_begin"] = int_or_text(p.ranges[0].begin);
    m["spp_end"] = int_or_text(p.ranges[0].end);
  }
  // an int where it fits (every seed below 2^31), else the decimal text
  if (p.id.seed <= 2147483647) m["seed"] = int(p.id.seed);
  else m["seed"] = std::to_string(p.id.seed);
  for (const RecordedChoice& c : recorded_choices())
    if (!c.only_when_set || !(p.id.*c.field).empty()) m[c.key] = p.id.*c.field;
  m["version"] = p.id.version;
  m["scene_hash"] = p.id.scene_hash;
  m["pixel_bounds"] = fmt::format("{},{},{},{}", p.x0, p.x0 + p.width, p.y0, p.y0 + p.height);
  m["full_resolution"] = fmt::format("{}x{}", p.id.full_width, p.id.full_height);
  m["interrupted"] = p.interrupted ? 1 : 0;
  if (!p.pixel_samples.empty()) m["adaptive"] = 1;  // its 'samples' layer: a merge refuses it (piece_from_header)
  return m;
}

// The EXR channels of a piece (docs/aov.md) from its sums, n samples: R, G, B (with alpha the
// transparent film's: premultiplied, without the environment layer), A
// (the mean of AR, AG, AB) and AR, AG, AB, environment.R/G/B, variance.R/G/B (the variance of the
// pixel's mean: (S2 - S1^2 / n) / (n (n - 1)), 0 below 2 samples), emission.R/G/B, direct.R/G/B,
// indirect.R/G/B (means), albedo.R/G/B and depth.Z (means over the samples whose camera ray
// collided, 0 where none did) and collision.fraction (the fraction that collided, their weight in a merge),
// shadow.R/G/B (the shadowed over the unshadowed sum, 1 where that is 0) and unshadowed.R/G/B (its mean,
// the ratio's weight in a merge).
std::vector<std::string> piece_exr_channels(const FilmPiece& p, std::vector<float>* px) {
  const uint32_t aovs = p.id.aovs;
  const bool alpha = aovs & ST_AOV_BIT(ALPHA);
  const std::vector<std::string> sums = aov_sum_channels(aovs);
  auto at = [&](const std::string& name) { return size_t(std::find(sums.begin(), sums.end(), name) - sums.begin()); };
  // each channel's recipe, decided once (not per pixel), in the table's order (aov_exr_channels)
  enum Kind { kBeauty, kAlphaMean, kMean, kVariance, kPerCollision, kCollisionFraction, kRatio };
  struct Channel {
    Kind kind;
    size_t col = 0;      // its sum's column in aov_sum (kVariance: the second moment's)
    int k = 0;           // kBeauty, kVariance: the colour channel
    size_t env_col = 0;  // kVariance with alpha: the environment's column (the whole beauty); kRatio: the denominator's
  };
  std::vector<std::string> names = {"R", "G", "B"};
  std::vector<Channel> recipe = {{kBeauty, 0, 0}, {kBeauty, 0, 1}, {kBeauty, 0, 2}};
  for (int k = 0; k < ST_AOV_COUNT; ++k) {
    if (!(aovs & (1u << k))) continue;
    const std::vector<std::string>& chans = aov_exr_channels(k);
    for (size_t c = 0; c < chans.size(); ++c) {
      names.push_back(chans[c]);
      if (k == ST_AOV_INDEX_ALPHA) recipe.push_back(c == 0 ? Channel{kAlphaMean} : Channel{kMean, at(chans[c])});
      else if (k == ST_AOV_INDEX_VARIANCE)
        recipe.push_back({kVariance, at("moment2." + chans[c].substr(chans[c].size() - 1)), int(c),
                          alpha ? at("environment." + chans[c].substr(chans[c].size() - 1)) : 0});
      else if (k == ST_AOV_INDEX_ALBEDO || k == ST_AOV_INDEX_DEPTH) recipe.push_back({kPerCollision, at(chans[c])});
      else if (k == ST_AOV_INDEX_SHADOW && c < 3) recipe.push_back({kRatio, at(chans[c]), 0, at(chans[c + 3])});
      else recipe.push_back({kMean, at(chans[c])});
    }
  }
  const bool collisions = aovs & (ST_AOV_BIT(ALBEDO) | ST_AOV_BIT(DEPTH));
  if (collisions) {
    names.push_back(kCollisionChannel);
    recipe.push_back({kCollisionFraction, at(kCollisionChannel)});
  }
  const bool adaptive = !p.pixel_samples.empty(), denoised = !p.denoised.empty();
  const size_t first_extra = names.size();
  if (adaptive) names.push_back(kSamplesChannel);
  if (denoised)
    for (const char* c : kDenoisedChannels) names.push_back(c);
  const size_t hits_col = collisions ? at(kCollisionChannel) : 0;
  const size_t a_col[3] = {at("AR"), at("AG"), at("AB")};
  const size_t na = sums.size(), nc = names.size(), npix = size_t(p.width) * p.height;
  const double n = double(p.samples());
  px->assign(npix * nc, 0.0f);
  if (n <= 0) return names;
  for (size_t i = 0; i < npix; ++i) {
    const double* a = na ? &p.aov_sum[i * na] : nullptr;
    float* o = &(*px)[i * nc];
    if (adaptive) o[first_extra] = p.pixel_samples[i];
    if (denoised)
      for (size_t c = 0; c < 3; ++c) o[first_extra + (adaptive ? 1 : 0) + c] = p.denoised[i * 3 + c];
    for (size_t c = 0; c < recipe.size(); ++c) {
      const Channel& ch = recipe[c];
      switch (ch.kind) {
        case kBeauty: o[c] = float(p.sum[i * 3 + size_t(ch.k)] / n); break;
        case kAlphaMean: o[c] = float((a[a_col[0]] + a[a_col[1]] + a[a_col[2]]) / (3.0 * n)); break;
        case kMean: o[c] = float(a[ch.col] / n); break;
        case kVariance: {
          const double s1 = p.sum[i * 3 + size_t(ch.k)] + (alpha ? a[ch.env_col] : 0.0);  // the whole beauty
          const double s2 = a[ch.col];
          // finite always: a sum of squares that overflowed float (samples above ~1e19) is written
          // as the largest float, not inf, which no reader (nor merge) would accept
          const double var = n >= 2 ? std::max(0.0, (s2 - s1 * s1 / n) / (n * (n - 1))) : 0.0;
          o[c] = std::isfinite(var) ? float(std::min(var, double(std::numeric_limits<float>::max())))
                                    : std::numeric_limits<float>::max();
          break;
        }
        case kPerCollision: o[c] = a[hits_col] != 0 ? float(a[ch.col] / a[hits_col]) : 0.0f; break;
        case kCollisionFraction: o[c] = float(a[ch.col] / n); break;
        case kRatio: o[c] = a[ch.env_col] != 0 ? float(a[ch.col] / a[ch.env_col]) : 1.0f; break;
      }
    }
  }
  return names;
}

std::vector<float> piece_beauty(const FilmPiece& p) {
  std::vector<float> rgb = p.mean();
  const std::vector<std::string> sums = aov_sum_channels(p.id.aovs);
  const size_t na = sums.size();
  const size_t e = size_t(std::find(sums.begin(), sums.end(), "environment.R") - sums.begin());
  if ((p.id.aovs & ST_AOV_BIT(ALPHA)) && p.samples() > 0)
    for (size_t i = 0; i < rgb.size(); ++i)
      rgb[i] = float((p.sum[i] + p.aov_sum[(i / 3) * na + e + i % 3]) / double(p.samples()));
  return rgb;
}

PixelWindow piece_window(const FilmPiece& p) {
  PixelWindow w;
  w.full_width = p.id.full_width;
  w.full_height = p.id.full_height;
  w.x0 = p.x0;
  w.y0 = p.y0;
  return w;
}

void write_piece(const std::string& path, const FilmPiece& p, const Metadata& extra, const ExrOptions& exr) {
  Metadata m = extra;
  for (auto& [k, v] : piece_metadata(p)) m[k] = v;
  const PixelWindow w = piece_window(p);
  std::string ext = lower_extension(path);
  if (ext != ".exr") {  // a PNG preview: the whole beauty (a transparent film's environment added back)
    write_image(path, p.width, p.height, piece_beauty(p), m, w);
    return;
  }
  std::vector<float> px;
  std::vector<std::string> names = piece_exr_channels(p, &px);
  write_exr_channels(path, p.width, p.height, names, px, m, w, exr);
}

namespace {

// A metadata value as text; throws Error naming the key when it is missing.
std::string meta_text(const std::string& path, const Metadata& meta, const char* key) {
  auto it = meta.find(key);
  if (it == meta.end())
    throw Error(fmt::format("{}: not a spectrack render that can be merged: metadata spectrack:{} is missing", path, key));
  if (auto s = std::get_if<std::string>(&it->second)) return *s;
  if (auto i = std::get_if<int>(&it->second)) return std::to_string(*i);
  return fmt::format("{}", std::get<float>(it->second));
}

// A metadata integer (an int, or decimal text where it did not fit one).
int64_t meta_integer(const std::string& path, const Metadata& meta, const char* key) {
  const std::string text = meta_text(path, meta, key);
  try {
    size_t used = 0;
    const long long v = std::stoll(text, &used);
    if (used == text.size()) return v;
  } catch (const std::exception&) {
  }
  throw Error(fmt::format("{}: metadata spectrack:{} '{}' is not an integer", path, key, text));
}

// spectrack:spp_ranges is the piece's sample set; spp, spp_begin and spp_end repeat it and must
// agree, or the file was edited or damaged and its pixels (means over spp samples) cannot be
// turned back into sums.
void check_sample_counts(const std::string& path, const Metadata& meta, const std::vector<SampleRange>& ranges) {
  const std::string listed = format_ranges(ranges);
  const int64_t n = count_samples(ranges);
  const int64_t spp = meta_integer(path, meta, "spp");
  if (spp != n)
    throw Error(fmt::format("{}: metadata spectrack:spp {} disagrees with spectrack:spp_ranges {} ({} samples); the "
                            "file was edited or damaged, refusing to merge it",
                            path, spp, listed, n));
  const bool has_begin = meta.count("spp_begin"), has_end = meta.count("spp_end");
  if (!has_begin && !has_end) return;
  const int64_t b = has_begin ? meta_integer(path, meta, "spp_begin") : -1;
  const int64_t e = has_end ? meta_integer(path, meta, "spp_end") : -1;
  if (ranges.size() != 1 || b != ranges[0].begin || e != ranges[0].end)
    throw Error(fmt::format("{}: metadata spectrack:spp_begin {} and spp_end {} disagree with spectrack:spp_ranges {}; "
                            "the file was edited or damaged, refusing to merge it",
                            path, has_begin ? std::to_string(b) : "(missing)", has_end ? std::to_string(e) : "(missing)",
                            listed));
}

// The layers a piece holds: each one whole, or the file is not one of ours.
uint32_t piece_layers(const std::string& path, const std::vector<std::string>& have) {
  auto has = [&](const std::string& c) { return std::find(have.begin(), have.end(), c) != have.end(); };
  uint32_t aovs = 0;
  for (int k = 0; k < ST_AOV_COUNT; ++k) {
    const std::vector<std::string>& chans = aov_exr_channels(k);
    size_t found = 0;
    for (auto& c : chans) found += has(c);
    if (found == chans.size()) aovs |= 1u << k;
    else if (found > 0)
      throw Error(fmt::format("{}: the {} layer is incomplete (it needs channels {}); a merge needs every channel of "
                              "a layer",
                              path, aov_name(k), fmt::join(chans, ", ")));
  }
  if ((aovs & ST_AOV_BIT(ALPHA)) && !(aovs & ST_AOV_BIT(ENVIRONMENT)))
    throw Error(fmt::format("{}: has an alpha layer without the environment layer that its transparent R, G, B leave "
                            "out; a merge cannot restore the beauty",
                            path));
  if ((aovs & (ST_AOV_BIT(ALBEDO) | ST_AOV_BIT(DEPTH))) && !has(kCollisionChannel))
    throw Error(fmt::format("{}: has an albedo or depth layer without its collision.fraction channel (how many samples' "
                            "camera rays collided), which a merge needs to weigh it",
                            path));
  return aovs;
}

}  // namespace

FilmPiece piece_from_header(const std::string& path, const RgbImage& img, bool keep_adaptive) {
  if (img.format != "openexr")
    throw Error(fmt::format("{}: a {} image cannot be merged: only spectrack's EXR outputs hold the float pixels and "
                            "sample ranges a merge needs",
                            path, img.format));
  if (img.meta.count("adaptive") && !keep_adaptive) throw adaptive_merge_error(path);
  auto str = [&](const char* key) { return meta_text(path, img.meta, key); };
  FilmPiece p;
  p.source = path;
  p.id.scene_hash = str("scene_hash");
  for (const RecordedChoice& c : recorded_choices())
    if (c.required || img.meta.count(c.key)) p.id.*c.field = str(c.key);
  p.id.version = str("version");
  try {
    p.id.seed = std::stoll(str("seed"));
  } catch (const std::exception&) {
    throw Error(fmt::format("{}: metadata spectrack:seed '{}' is not a number", path, str("seed")));
  }
  p.ranges = join_ranges(parse_ranges(str("spp_ranges"), path + ": metadata spectrack:spp_ranges"));
  check_sample_counts(path, img.meta, p.ranges);
  p.interrupted = str("interrupted") != "0";
  p.id.full_width = img.window.full_width;
  p.id.full_height = img.window.full_height;
  p.x0 = img.window.x0;
  p.y0 = img.window.y0;
  p.width = img.width;
  p.height = img.height;
  p.id.aovs = piece_layers(path, img.extra_names);
  return p;
}

PieceDecoder::PieceDecoder(const FilmPiece& p, const std::vector<std::string>& have)
    : n_(double(p.samples())), alpha_(p.id.aovs & ST_AOV_BIT(ALPHA)), ne_(have.size()) {
  auto column = [&](const std::string& c) { return size_t(std::find(have.begin(), have.end(), c) - have.begin()); };
  const std::vector<std::string> sums = aov_sum_channels(p.id.aovs);
  src_.resize(sums.size());
  for (size_t c = 0; c < sums.size(); ++c) {
    const std::string& name = sums[c];
    if (name.rfind("moment2.", 0) == 0) {
      const std::string ch(1, name.back());
      src_[c].moment_of = int(std::string("RGB").find(name.back()));
      src_[c].col = column("variance." + ch);
      if (alpha_) src_[c].env_col = column("environment." + ch);
    } else {
      src_[c].col = column(name);  // AR, AG, AB, environment.*, the passes, albedo, depth, shadow, collision.fraction
      for (int k : {ST_AOV_INDEX_ALBEDO, ST_AOV_INDEX_DEPTH})
        for (const std::string& a : aov_exr_channels(k)) src_[c].per_collision = src_[c].per_collision || name == a;
      if (name.rfind("shadow.", 0) == 0) src_[c].ratio_of = c + 3;  // its unshadowed sum, decoded first
    }
  }
  hits_col_ = column(kCollisionChannel);
}

void PieceDecoder::decode(const float* rgb, const float* extra, size_t npix, double* sum, double* aov_sum) const {
  const double n = n_;
  const size_t na = src_.size(), ne = ne_;
  for (size_t i = 0; i < npix; ++i) {
    const float* e = ne ? &extra[i * ne] : nullptr;
    for (int k = 0; k < 3; ++k) sum[i * 3 + k] = double(rgb[i * 3 + k]) * n;
    for (size_t c = na; c-- > 0;) {  // backwards: a ratio's weight comes after it
      const Source& sc = src_[c];
      double v = double(e[sc.col]);
      if (sc.moment_of >= 0) {  // back from the variance of the mean (piece_exr_channels)
        double s1 = sum[i * 3 + size_t(sc.moment_of)];  // the whole beauty's sum
        if (alpha_) s1 += double(e[sc.env_col]) * n;
        v = v * n * (n - 1) + (n > 0 ? s1 * s1 / n : 0.0);
      } else if (sc.per_collision) {
        v *= double(e[hits_col_]) * n;
      } else if (sc.ratio_of > 0) {  // the shadow layer: the ratio times its decoded denominator
        v *= aov_sum[i * na + sc.ratio_of];
      } else {
        v *= n;
      }
      aov_sum[i * na + c] = v;
    }
  }
}

FilmPiece read_piece(const std::string& path, Metadata* meta, bool keep_adaptive) {
  RgbImage img = read_image(path, ImageUse::kFilmPiece);
  if (meta) *meta = img.meta;
  FilmPiece p = piece_from_header(path, img, keep_adaptive);
  const size_t npix = size_t(p.width) * p.height;
  p.sum.resize(npix * 3);
  p.aov_sum.resize(npix * aov_sum_channels(p.id.aovs).size());
  PieceDecoder(p, img.extra_names).decode(img.rgb.data(), img.extra.data(), npix, p.sum.data(), p.aov_sum.data());
  const std::vector<std::string>& have = img.extra_names;
  const size_t ne = have.size();
  auto column = [&](const char* c) { return size_t(std::find(have.begin(), have.end(), c) - have.begin()); };
  if (img.meta.count("adaptive")) {  // keep_adaptive (piece_from_header refuses it otherwise)
    const size_t col = column(kSamplesChannel);
    if (col == ne)
      throw Error(fmt::format("{}: metadata spectrack:adaptive without the '{}' layer (the samples of each pixel); the "
                              "file was edited or damaged",
                              path, kSamplesChannel));
    p.pixel_samples.resize(npix);
    for (size_t i = 0; i < npix; ++i) p.pixel_samples[i] = img.extra[i * ne + col];
  }
  const size_t d[3] = {column(kDenoisedChannels[0]), column(kDenoisedChannels[1]), column(kDenoisedChannels[2])};
  if (d[0] < ne && d[1] < ne && d[2] < ne) {
    p.denoised.resize(npix * 3);
    for (size_t i = 0; i < npix; ++i)
      for (size_t c = 0; c < 3; ++c) p.denoised[i * 3 + c] = img.extra[i * ne + d[c]];
  }
  return p;
}

}  // namespace spectrack
