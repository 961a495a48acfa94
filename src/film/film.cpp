// film.cpp: see film.h. merge_pieces cuts the bounding box of the pieces into the rectangles
// between consecutive window edges; within one rectangle every pixel is covered by the same
// pieces, so coverage, overlap and sample-set checks are done once per rectangle (a few thousand
// for hundreds of tiles) and only the sums are added per pixel.
#include "film/film.h"

#include <OpenImageIO/hash.h>
#include <fmt/format.h>
#include <fmt/ranges.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <fstream>
#include <cmath>
#include <limits>
#include <sstream>
#include <tuple>

namespace spectrack {

std::string format_ranges(const std::vector<SampleRange>& ranges) {
  std::string s;
  for (auto& r : ranges) s += (s.empty() ? "" : ",") + fmt::format("{}:{}", r.begin, r.end);
  return s;
}

std::vector<SampleRange> parse_ranges(const std::string& text, const std::string& what) {
  std::vector<SampleRange> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    SampleRange r;
    size_t colon = item.find(':');
    try {
      size_t a = 0, b = 0;
      if (colon == std::string::npos) throw std::invalid_argument("no colon");
      r.begin = std::stoll(item.substr(0, colon), &a);
      r.end = std::stoll(item.substr(colon + 1), &b);
      if (a != colon || b != item.size() - colon - 1) throw std::invalid_argument("trailing text");
    } catch (const std::exception&) {
      throw Error(fmt::format("{}: '{}' is not a sample range A:B", what, item));
    }
    if (r.begin < 0 || r.end <= r.begin)
      throw Error(fmt::format("{}: sample range '{}' is empty or negative", what, item));
    out.push_back(r);
  }
  if (out.empty()) throw Error(fmt::format("{}: no sample range in '{}'", what, text));
  return out;
}

std::vector<SampleRange> join_ranges(std::vector<SampleRange> ranges) {
  std::sort(ranges.begin(), ranges.end(), [](auto& a, auto& b) { return a.begin < b.begin; });
  std::vector<SampleRange> out;
  for (auto& r : ranges) {
    if (r.end <= r.begin) continue;
    if (!out.empty() && r.begin <= out.back().end) out.back().end = std::max(out.back().end, r.end);
    else out.push_back(r);
  }
  return out;
}

int64_t count_samples(const std::vector<SampleRange>& ranges) {
  int64_t n = 0;
  for (auto& r : ranges) n += r.end - r.begin;
  return n;
}

static void hash_file(OIIO::SHA1& h, const std::string& path, const std::string& what) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw Error(fmt::format("{}: cannot read {} to hash the scene", what, path));
  std::vector<char> buf(1 << 20);
  uint64_t total = 0;
  while (f) {
    f.read(buf.data(), std::streamsize(buf.size()));
    std::streamsize n = f.gcount();
    if (n > 0) h.append(buf.data(), size_t(n));
    total += uint64_t(std::max<std::streamsize>(n, 0));
  }
  h.append(&total, sizeof(total));
}

std::string scene_hash(const SceneDesc& scene) {
  std::ifstream f(scene.path, std::ios::binary);
  if (!f) throw Error(fmt::format("{}: cannot read the scene file to hash it", scene.path));
  std::stringstream text;
  text << f.rdbuf();
  return scene_hash(scene, text.str());
}

std::string scene_hash(const SceneDesc& scene, const std::string& json_text) {
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(json_text);
  } catch (const std::exception& e) {
    throw Error(fmt::format("{}: cannot parse the scene file to hash it: {}", scene.path, e.what()));
  }
  if (j.is_object()) {
    if (j.contains("film") && j["film"].is_object()) {
      // how the film is stored, not what it holds (the layers are compared on their own: id.aovs)
      for (const char* k : {"output", "spp", "alpha", "aovs", "half", "compression"}) j["film"].erase(k);
    }
    if (j.contains("render") && j["render"].is_object())
      for (const char* k : {"seed", "tracker", "spectral_scheme", "absorption", "light_sampling", "transmittance", "lookup", "color",
                            "noise_target", "equiangular", "time_limit", "wavelength_sampling"})
        j["render"].erase(k);
    // file names stand for their contents, hashed below: a scene whose assets moved is the same scene
    for (const char* list : {"media", "lights"})
      if (j.contains(list) && j[list].is_array())
        for (auto& item : j[list])
          for (const char* k : {"file", "map"})
            if (item.is_object() && item.contains(k)) item[k] = "";
  }
  OIIO::SHA1 h;
  h.append(std::string("spectrack-scene-hash/1\n") + j.dump());
  for (auto& m : scene.media)
    if (m.type == ST_MEDIUM_VDB) hash_file(h, m.file, scene.path + ": " + m.json_path + "/file");
  for (auto& l : scene.lights)
    if (!l.map.empty()) hash_file(h, l.map, scene.path + ": " + l.json_path + "/map");
  return h.digest();
}

RenderIdentity render_identity(const RenderSettings& s) {
  RenderIdentity id;
  id.full_width = s.full_width;
  id.full_height = s.full_height;
  id.seed = s.seed;
  id.tracker = tracker_name(s.tracker);
  id.scheme = scheme_name(s.scheme);
  id.absorption = absorption_name(s.absorption);
  id.light_sampling = light_sampling_name(s.light_sampling);
  id.transmittance = transmittance_name(s.transmittance);
  id.lookup = lookup_name(s.lookup);
  id.color = film_color_name(s.color);
  if (s.color == ST_FILM_COLOR_SPECTRAL) id.wavelength_sampling = wavelength_sampling_name(s.wavelength_sampling);
  id.guided = s.guiding ? "on" : "off";
  id.guide_splitting = s.guide_splitting ? "on" : "off";
  id.equiangular = guiding_name(s.equiangular);
  id.aovs = s.aovs;
  if (s.shutter) id.shutter = fmt::format("{}:{}/{}", (*s.shutter)[0], (*s.shutter)[1], s.time_strata);
  id.iteration_budget = std::to_string(s.iteration_budget);
  id.majorant = majorant_identity(s.majorant_cell, s.majorant_block, s.majorant_step_cost);
  if (s.transmittance == ST_TRANSMITTANCE_RAY_MARCHING)
    id.ray_marching = fmt::format("spacing {}, pilot {}", s.march_spacing, s.pilot_spacing);
  id.version = SPECTRACK_VERSION;
  return id;
}

std::string majorant_identity(int cell, int block, const std::optional<double>& step_cost) {
  return fmt::format("cell {}, block {}, step cost {}", cell > 0 ? std::to_string(cell) : "auto",
                     std::max(block, 1),  // 0 and 1: one level alike
                     step_cost ? fmt::format("{}", *step_cost) : std::string("auto"));
}

const std::vector<RecordedChoice>& recorded_choices() {
  static const std::vector<RecordedChoice> list = {
      {"tracker", &RenderIdentity::tracker, "the tracker", true},
      {"scheme", &RenderIdentity::scheme, "the spectral scheme", true},
      {"absorption", &RenderIdentity::absorption, "the absorption mode", false},
      {"light_sampling", &RenderIdentity::light_sampling, "the light sampling", false},
      {"transmittance", &RenderIdentity::transmittance, "the transmittance estimator", false},
      {"lookup", &RenderIdentity::lookup, "the density lookup mode", false},
      {"color", &RenderIdentity::color, "the colour mode", false},
      {"wavelength_sampling", &RenderIdentity::wavelength_sampling, "the wavelength sampling", false, true},
      {"guided", &RenderIdentity::guided, "volume path guiding (as run)", false},
      {"guide_splitting", &RenderIdentity::guide_splitting, "guided roulette and splitting", false},
      {"equiangular", &RenderIdentity::equiangular, "equi-angular sampling", false},
      {"iteration_budget", &RenderIdentity::iteration_budget, "the iteration budget (--budget)", false},
      {"majorant", &RenderIdentity::majorant, "the majorant grid (--majorant-cell, --majorant-block, --majorant-step-cost)",
       false},
      {"ray_marching", &RenderIdentity::ray_marching, "the ray-marching spacings (--march-spacing, --pilot-spacing)", false,
       true},
      {"shutter", &RenderIdentity::shutter, "the shutter (open:close/strata)", false, true},
      {"frame", &RenderIdentity::frame, "the frame", false, true},
      {"camera", &RenderIdentity::camera, "the camera (framed over the sequence's frames)", false, true},
  };
  return list;
}

FilmPiece empty_piece(const RenderIdentity& id, const FilmWindow& w, const std::string& source) {
  FilmPiece p;
  p.source = source;
  p.id = id;
  p.x0 = w.x0, p.y0 = w.y0, p.width = w.width, p.height = w.height;
  p.sum.assign(size_t(w.pixels()) * 3, 0.0);
  p.aov_sum.assign(size_t(w.pixels()) * aov_sum_channels(id.aovs).size(), 0.0);
  return p;
}

std::vector<float> FilmPiece::mean() const {
  std::vector<float> m(sum.size(), 0.0f);
  int64_t n = samples();
  if (n > 0)
    for (size_t i = 0; i < sum.size(); ++i) m[i] = float(sum[i] / double(n));
  return m;
}

FilmPiece piece_from_result(const RenderResult& r, const RenderIdentity& id, const std::string& source) {
  FilmPiece p;
  p.source = source;
  p.id = id;
  p.x0 = r.x0;
  p.y0 = r.y0;
  p.width = r.width;
  p.height = r.height;
  if (r.spp_done > 0) p.ranges = {{r.sample_begin, r.sample_begin + r.spp_done}};
  p.sum = r.sum;
  p.aov_sum = r.aov_sum;
  p.interrupted = r.interrupted;
  return p;
}

static std::string layer_list(uint32_t aovs) {
  std::string s;
  for (int k = 0; k < ST_AOV_COUNT; ++k)
    if (aovs & (1u << k)) s += (s.empty() ? "" : ",") + std::string(aov_name(k));
  return s.empty() ? "none" : s;
}

static std::string window_text(int x0, int x1, int y0, int y1) {
  return fmt::format("x {}..{}, y {}..{}", x0, x1 - 1, y0, y1 - 1);
}

namespace {

// Every piece belongs to the render of the first one and holds samples inside the film.
// (with_sums: and holds the sums of its window; a header read for a streamed merge holds none).
void check_one_render(const std::vector<FilmPiece>& pieces, bool with_sums) {
  const FilmPiece& a = pieces[0];
  for (auto& p : pieces) {
    auto differ = [&](const std::string& what, const std::string& va, const std::string& vb) {
      throw Error(fmt::format("merge: {} and {} are not parts of one render: {} differs ({} vs {})", a.source,
                              p.source, what, va, vb));
    };
    if (p.id.full_width != a.id.full_width || p.id.full_height != a.id.full_height)
      differ("the resolution", fmt::format("{}x{}", a.id.full_width, a.id.full_height),
             fmt::format("{}x{}", p.id.full_width, p.id.full_height));
    if (p.id.seed != a.id.seed) differ("the seed", std::to_string(a.id.seed), std::to_string(p.id.seed));
    auto shown = [](const std::string& v) { return v.empty() ? std::string("none") : v; };
    for (const RecordedChoice& c : recorded_choices())
      if (p.id.*c.field != a.id.*c.field) differ(c.what, shown(a.id.*c.field), shown(p.id.*c.field));
    if (p.id.aovs != a.id.aovs) differ("the set of film layers", layer_list(a.id.aovs), layer_list(p.id.aovs));
    if (p.id.version != a.id.version) differ("the spectrack version", a.id.version, p.id.version);
    if (p.id.scene_hash != a.id.scene_hash) differ("the scene (spectrack:scene_hash)", a.id.scene_hash, p.id.scene_hash);
    if (p.width <= 0 || p.height <= 0 || p.x0 < 0 || p.y0 < 0 || p.x0 + p.width > p.id.full_width ||
        p.y0 + p.height > p.id.full_height ||
        (with_sums && (p.sum.size() != size_t(p.width) * p.height * 3 ||
                       p.aov_sum.size() != size_t(p.width) * p.height * aov_sum_channels(p.id.aovs).size())))
      throw Error(fmt::format("merge: {}: pixel window {} is not inside the {}x{} film", p.source,
                              window_text(p.x0, p.x0 + p.width, p.y0, p.y0 + p.height), p.id.full_width,
                              p.id.full_height));
    if (p.samples() == 0) throw Error(fmt::format("merge: {}: holds no sample", p.source));
  }
}

// The sample ranges that the pieces covering cell (a rectangle between window edges) hold, joined;
// throws when none covers it or two overlap.
std::vector<SampleRange> cell_ranges(const std::vector<FilmPiece>& pieces, int cx0, int cx1, int cy0, int cy1,
                                     const std::string& box) {
  std::string cell = window_text(cx0, cx1, cy0, cy1);
  std::vector<std::pair<SampleRange, size_t>> held;
  for (size_t i = 0; i < pieces.size(); ++i) {
    const FilmPiece& p = pieces[i];
    if (p.x0 <= cx0 && cx1 <= p.x0 + p.width && p.y0 <= cy0 && cy1 <= p.y0 + p.height)
      for (auto& r : p.ranges) held.push_back({r, i});
  }
  if (held.empty())
    throw Error(fmt::format("merge: pixels {} lie inside the inputs' bounding box ({}) but in no input: a tile "
                            "is missing",
                            cell, box));
  std::sort(held.begin(), held.end(), [](auto& p, auto& q) { return p.first.begin < q.first.begin; });
  for (size_t k = 1; k < held.size(); ++k)
    if (held[k].first.begin < held[k - 1].first.end)
      throw Error(fmt::format("merge: {} and {} overlap: both hold samples {}:{} of pixels {}",
                              pieces[held[k - 1].second].source, pieces[held[k].second].source,
                              held[k].first.begin, std::min(held[k].first.end, held[k - 1].first.end), cell));
  std::vector<SampleRange> rs;
  for (auto& h : held) rs.push_back(h.first);
  return join_ranges(rs);
}

FilmPiece merge_layout(const std::vector<FilmPiece>& pieces, bool with_sums) {
  if (pieces.empty()) throw Error("merge: no input");
  for (const FilmPiece& p : pieces)
    if (!p.pixel_samples.empty()) throw adaptive_merge_error(p.source);
  check_one_render(pieces, with_sums);
  const FilmPiece& a = pieces[0];
  std::vector<int> xs, ys;
  for (auto& p : pieces) {
    xs.insert(xs.end(), {p.x0, p.x0 + p.width});
    ys.insert(ys.end(), {p.y0, p.y0 + p.height});
  }
  std::sort(xs.begin(), xs.end());
  xs.erase(std::unique(xs.begin(), xs.end()), xs.end());
  std::sort(ys.begin(), ys.end());
  ys.erase(std::unique(ys.begin(), ys.end()), ys.end());

  FilmPiece out;
  out.source = "merge";
  out.id = a.id;
  out.x0 = xs.front();
  out.y0 = ys.front();
  out.width = xs.back() - out.x0;
  out.height = ys.back() - out.y0;
  bool first_cell = true;
  std::string first_cell_text;
  for (size_t yi = 0; yi + 1 < ys.size(); ++yi)
    for (size_t xi = 0; xi + 1 < xs.size(); ++xi) {
      int cx0 = xs[xi], cx1 = xs[xi + 1], cy0 = ys[yi], cy1 = ys[yi + 1];
      std::string cell = window_text(cx0, cx1, cy0, cy1);
      std::vector<SampleRange> rs =
          cell_ranges(pieces, cx0, cx1, cy0, cy1, window_text(out.x0, out.x0 + out.width, out.y0, out.y0 + out.height));
      if (first_cell) {
        out.ranges = rs;
        first_cell_text = cell;
        first_cell = false;
      } else if (format_ranges(rs) != format_ranges(out.ranges)) {
        throw Error(fmt::format("merge: pixels {} would hold samples {} but pixels {} hold {}: every pixel needs the "
                                "same samples (is a shard missing for some tiles?)",
                                cell, format_ranges(rs), first_cell_text, format_ranges(out.ranges)));
      }
    }
  for (auto& p : pieces) out.interrupted |= p.interrupted;
  return out;
}

}  // namespace

UsageError adaptive_merge_error(const std::string& source) {
  return UsageError(fmt::format("{}: an adaptive render cannot be merged: each pixel holds its own number of samples "
                                "(layer 'samples'), so no other piece adds to it (docs/adaptive.md)",
                                source));
}

FilmPiece plan_merge(const std::vector<FilmPiece>& pieces) { return merge_layout(pieces, false); }

FilmPiece merge_pieces(const std::vector<FilmPiece>& pieces) {
  FilmPiece out = merge_layout(pieces, true);
  const FilmPiece& a = pieces[0];
  const size_t na = aov_sum_channels(a.id.aovs).size();
  out.sum.assign(size_t(out.width) * out.height * 3, 0.0);
  out.aov_sum.assign(size_t(out.width) * out.height * na, 0.0);
  for (auto& p : pieces) {
    for (auto [from, to, nc] : {std::tuple{&p.sum, &out.sum, size_t(3)}, std::tuple{&p.aov_sum, &out.aov_sum, na}})
      for (int y = 0; y < p.height && nc > 0; ++y) {
        const double* src = &(*from)[size_t(y) * p.width * nc];
        double* dst = &(*to)[(size_t(p.y0 - out.y0 + y) * out.width + (p.x0 - out.x0)) * nc];
        for (size_t i = 0; i < size_t(p.width) * nc; ++i) dst[i] += src[i];
      }
  }
  return out;
}

}  // namespace spectrack
