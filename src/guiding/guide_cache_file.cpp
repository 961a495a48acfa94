// guide_cache_file.cpp: see guide_cache_file.h. The checks of a read cache are those a kernel
// relies on: every cell's kd-tree ends in a leaf within ST_GUIDE_MAX_DEPTH levels whose region
// exists, every value a sampler or a weight reads is finite and in its range.
#include "guiding/guide_cache_file.h"

#include <fmt/format.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <vector>

#include "util/error.h"
#include "util/output_file.h"

namespace spectrack {

namespace {

constexpr char kMagic[] = "spectrack-guide-cache 1";

// The byte counts and struct sizes that the key carries beside the caller's fields.
nlohmann::json layout(const GuideCache& c) {
  return {{"regions", c.regions.size()},
          {"nodes", c.nodes.size()},
          {"pixels", c.pixel_estimate.size()},
          {"header_bytes", sizeof(st_guide_header)},
          {"region_bytes", sizeof(st_guide_region)},
          {"node_bytes", sizeof(st_guide_node)},
          {"vmf_lobes", ST_VMF_LOBES}};
}

bool finite_in(float v, float lo, float hi) { return std::isfinite(v) && v >= lo && v <= hi; }

// Why the regions, nodes or pixel estimates of a read cache cannot reach a kernel, or "".
std::string damage(const GuideCache& c, const st_guide_header& fresh) {
  const st_guide_header& h = c.header;
  for (int a = 0; a < 3; ++a)
    if (h.dims[a] != fresh.dims[a] || std::memcmp(&(&h.origin.x)[a], &(&fresh.origin.x)[a], 4) != 0 ||
        std::memcmp(&(&h.inv_cell.x)[a], &(&fresh.inv_cell.x)[a], 4) != 0)
      return "its grid of cells is not this scene's";
  const size_t cells = size_t(h.dims[0]) * size_t(h.dims[1]) * size_t(h.dims[2]);
  if (h.regions != int(c.regions.size()) || h.nodes != int(c.nodes.size()) || c.nodes.size() < cells ||
      c.regions.empty() || c.regions.size() > kGuideMaxRegions)
    return "its region and node counts do not fit together";
  if (h.guided_depth < 1 || (h.phase_product != 0 && h.phase_product != 1) || h.depth < 0 || h.depth > ST_GUIDE_MAX_DEPTH)
    return "its header's guided depth, phase product or tree depth is out of range";
  for (size_t root = 0; root < cells; ++root) {  // every walk ends in an existing region
    std::vector<std::pair<uint32_t, int>> stack = {{uint32_t(root), 0}};
    while (!stack.empty()) {
      const auto [i, d] = stack.back();
      stack.pop_back();
      const st_guide_node& n = c.nodes[i];
      if (n.next & ST_GUIDE_LEAF) {
        if ((n.next & ~ST_GUIDE_LEAF) >= c.regions.size()) return fmt::format("node {} names a region that does not exist", i);
        continue;
      }
      const uint64_t child = uint64_t(n.next >> 2);
      if ((n.next & 3u) > 2u || child + 1 >= c.nodes.size() || child < cells || d + 1 >= ST_GUIDE_MAX_DEPTH ||
          !std::isfinite(n.split))
        return fmt::format("node {} of cell {} does not lead to a region", i, root);
      stack.push_back({uint32_t(child), d + 1}), stack.push_back({uint32_t(child + 1), d + 1});
    }
  }
  for (size_t r = 0; r < c.regions.size(); ++r) {
    const st_guide_region& g = c.regions[r];
    bool ok = finite_in(g.alpha, 0.0f, kGuideAlphaMax) && finite_in(g.records, 0.0f, 3.4e38f) &&
              finite_in(g.radiance, 0.0f, 3.4e38f) && std::isfinite(g.weight);
    for (int k = 0; k < ST_VMF_LOBES && ok; ++k) {
      const st_float4& l = g.mix.lobe[k];
      const double norm = std::sqrt(double(l.x) * l.x + double(l.y) * l.y + double(l.z) * l.z);
      ok = finite_in(g.mix.weight[k], 0.0f, 3.4e38f) && finite_in(l.w, 0.0f, 1e7f) &&
           (g.mix.weight[k] == 0.0f || std::abs(norm - 1.0) < 1e-3);
    }
    if (!ok) return fmt::format("region {} holds a value out of range (alpha, lobe, weight or radiance)", r);
  }
  for (size_t i = 0; i < c.pixel_estimate.size(); ++i)
    if (!finite_in(c.pixel_estimate[i], 0.0f, 3.4e38f)) return fmt::format("pixel estimate {} is not finite and >= 0", i);
  return "";
}

}  // namespace

void write_guide_cache_file(const std::string& path, const GuideCache& cache, const nlohmann::json& key) {
  nlohmann::json head = key;
  head["layout"] = layout(cache);
  const std::string text = std::string(kMagic) + "\n" + head.dump() + "\n";
  const std::vector<unsigned char> bytes = cache.serialize();
  OutputFile out(path);
  out.append(text.data(), text.size());
  out.append(bytes.data(), bytes.size());
  out.commit();
}

void read_guide_cache_file(const std::string& path, const nlohmann::json& key, GuideCache& cache) {
  auto fail = [&](const std::string& why) {
    return Error(fmt::format("{}: guide cache (--guide-cache): {}", path, why));
  };
  std::ifstream in(path, std::ios::binary);
  if (!in) throw fail("cannot be read");
  std::string magic, line;
  if (!std::getline(in, magic) || magic != kMagic) throw fail(fmt::format("not a spectrack guide cache (its first line is not '{}')", kMagic));
  if (!std::getline(in, line)) throw fail("ends before its key");
  nlohmann::json head;
  try {
    head = nlohmann::json::parse(line);
  } catch (const nlohmann::json::exception& e) {
    throw fail(fmt::format("its key is not JSON ({})", e.what()));
  }
  if (!head.is_object()) throw fail("its key is not a JSON object");
  for (auto& [field, want] : key.items()) {
    if (!head.contains(field)) throw fail(fmt::format("its key lacks the field '{}'", field));
    if (head[field] != want)
      throw fail(fmt::format("it was trained for another render: key field '{}' is {} in the file and {} in this render "
                             "(remove the file to train again, or name another)",
                             field, head[field].dump(), want.dump()));
  }
  const nlohmann::json& lay = head.contains("layout") ? head["layout"] : nlohmann::json();
  GuideCache shape;  // the counts the layout names, sizes checked against this build's
  try {
    const nlohmann::json built = layout(shape);
    for (const char* f : {"header_bytes", "region_bytes", "node_bytes", "vmf_lobes"})
      if (lay.at(f) != built.at(f)) throw fail(fmt::format("it was written by a build with another layout ({})", f));
    shape.regions.resize(lay.at("regions").get<size_t>());
    shape.nodes.resize(lay.at("nodes").get<size_t>());
    shape.pixel_estimate.resize(lay.at("pixels").get<size_t>());
  } catch (const nlohmann::json::exception& e) {
    throw fail(fmt::format("its layout is missing or not counts ({})", e.what()));
  } catch (const std::length_error&) {
    throw fail("its layout's counts are too large");
  }
  if (shape.regions.size() > kGuideMaxRegions || shape.nodes.size() > 4 * kGuideMaxRegions + (1u << 20) ||
      shape.pixel_estimate.size() != cache.pixel_estimate.size())
    throw fail(fmt::format("its counts do not fit this render ({} pixel estimates for a film of {} pixels)",
                           shape.pixel_estimate.size(), cache.pixel_estimate.size()));
  std::vector<char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (bytes.size() != shape.bytes())
    throw fail(fmt::format("it holds {} bytes after its key where its layout needs {} (truncated or damaged)", bytes.size(),
                           shape.bytes()));
  GuideCache c = cache;  // the host-only settings and the fresh grid stay the caller's
  size_t at = 0;
  auto take = [&](void* to, size_t n) {
    if (n) std::memcpy(to, bytes.data() + at, n);
    at += n;
  };
  take(&c.header, sizeof(st_guide_header));
  c.regions.resize(shape.regions.size());
  c.nodes.resize(shape.nodes.size());
  c.pixel_estimate.resize(shape.pixel_estimate.size());
  take(c.regions.data(), c.regions.size() * sizeof(st_guide_region));
  take(c.nodes.data(), c.nodes.size() * sizeof(st_guide_node));
  take(c.pixel_estimate.data(), c.pixel_estimate.size() * sizeof(float));
  if (const std::string why = damage(c, cache.header); !why.empty()) throw fail(why);
  c.node_depth.assign(c.nodes.size(), 0);  // refinement's, host only: a read cache is not refined
  cache = std::move(c);
}

}  // namespace spectrack
