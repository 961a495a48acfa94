// guide_cache_file.cpp: see guide_cache_file.h. The checks of a read cache are those a kernel
// relies on: every cell's kd-tree ends in a leaf within ST_GUIDE_MAX_DEPTH levels whose region
// exists, every value a sampler or a weight reads is finite and in its range.
#include "guiding/guide_cache_file.h"

#include <fmt/format.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <vector>

#include "util/error.h"
#include "util/files.h"
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
  if (h.regions != int(c.regions.size()) || h.nodes != int(c.nodes.size()))
    return "its header's region and node counts are not its layout's";
  if (h.guided_depth != fresh.guided_depth || h.phase_product != fresh.phase_product || h.depth < 0 ||
      h.depth > ST_GUIDE_MAX_DEPTH)
    return "its header's guided depth, phase product or tree depth is not this render's";
  // every cell's kd-tree: each node reached once, every walk ends in a leaf within
  // ST_GUIDE_MAX_DEPTH levels (guide_tree_leaf's bound) that names an existing region
  std::vector<char> seen(c.nodes.size(), 0);
  for (size_t root = 0; root < cells; ++root) {
    std::vector<std::pair<uint32_t, int>> stack = {{uint32_t(root), 0}};
    while (!stack.empty()) {
      const auto [i, d] = stack.back();
      stack.pop_back();
      if (seen[i]++) return fmt::format("node {} is reached twice (the cells' trees are not trees)", i);
      const st_guide_node& n = c.nodes[i];
      if (n.next & ST_GUIDE_LEAF) {
        if ((n.next & ~ST_GUIDE_LEAF) >= c.regions.size()) return fmt::format("node {} names a region that does not exist", i);
        continue;
      }
      const uint64_t child = uint64_t(n.next >> 2);
      if ((n.next & 3u) > 2u || child + 1 >= c.nodes.size() || child < cells || d + 1 > ST_GUIDE_MAX_DEPTH ||
          !std::isfinite(n.split))
        return fmt::format("node {} of cell {} does not lead to a region", i, root);
      stack.push_back({uint32_t(child), d + 1}), stack.push_back({uint32_t(child + 1), d + 1});
    }
  }
  for (size_t r = 0; r < c.regions.size(); ++r) {
    const st_guide_region& g = c.regions[r];
    bool ok = finite_in(g.alpha, 0.0f, kGuideAlphaMax) && finite_in(g.records, 0.0f, 1e30f) &&
              finite_in(g.radiance, 0.0f, 1e30f) && finite_in(g.weight, -1e30f, 1e30f);
    for (int k = 0; k < ST_VMF_LOBES && ok; ++k) {  // weights bounded so that their float sum stays finite
      const st_float4& l = g.mix.lobe[k];
      const double norm = std::sqrt(double(l.x) * l.x + double(l.y) * l.y + double(l.z) * l.z);
      ok = finite_in(g.mix.weight[k], 0.0f, 1e30f) && finite_in(l.w, 0.0f, 1e7f) &&
           (g.mix.weight[k] == 0.0f || std::abs(norm - 1.0) < 1e-3);
    }
    if (!ok) return fmt::format("region {} holds a value out of range (alpha, lobe, weight or radiance)", r);
  }
  for (size_t i = 0; i < c.pixel_estimate.size(); ++i)
    if (!finite_in(c.pixel_estimate[i], 0.0f, 1e30f)) return fmt::format("pixel estimate {} is not finite and >= 0", i);
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
  check_input_file(path, "guide cache (--guide-cache)");  // a FIFO would block, a folder is no cache
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
  // the counts, checked before anything is allocated: at most kGuideMaxRegions regions, two nodes
  // per region that refinement added to the grid's cells, one estimate per film pixel
  const size_t cells = size_t(cache.header.dims[0]) * size_t(cache.header.dims[1]) * size_t(cache.header.dims[2]);
  uint64_t regions = 0, nodes = 0, pixels = 0;
  try {
    const nlohmann::json built = layout(GuideCache{});
    for (const char* f : {"header_bytes", "region_bytes", "node_bytes", "vmf_lobes"})
      if (lay.at(f) != built.at(f)) throw fail(fmt::format("it was written by a build with another layout ({})", f));
    regions = lay.at("regions").get<uint64_t>(), nodes = lay.at("nodes").get<uint64_t>(), pixels = lay.at("pixels").get<uint64_t>();
  } catch (const nlohmann::json::exception& e) {
    throw fail(fmt::format("its layout is missing or not counts ({})", e.what()));
  }
  if (regions < cells || regions > kGuideMaxRegions || nodes != cells + 2 * (regions - cells) ||
      pixels != cache.pixel_estimate.size())
    throw fail(fmt::format("its counts do not fit this render ({} regions, {} nodes and {} pixel estimates for a grid of "
                           "{} cells and a film of {} pixels)",
                           regions, nodes, pixels, cells, cache.pixel_estimate.size()));
  const uint64_t need = sizeof(st_guide_header) + regions * sizeof(st_guide_region) + nodes * sizeof(st_guide_node) +
                        pixels * sizeof(float);
  const std::streampos body = in.tellg();
  in.seekg(0, std::ios::end);
  const uint64_t have = uint64_t(in.tellg() - body);
  in.seekg(body);
  if (have != need)
    throw fail(fmt::format("it holds {} bytes after its key where its layout needs {} (truncated or damaged)", have, need));
  GuideCache c = cache;  // the host-only settings stay the caller's
  c.regions.resize(regions);
  c.nodes.resize(nodes);
  c.pixel_estimate.resize(pixels);
  auto take = [&](void* to, size_t n) {
    if (n && !in.read(static_cast<char*>(to), std::streamsize(n))) throw fail("cannot be read to its end");
  };
  take(&c.header, sizeof(st_guide_header));
  take(c.regions.data(), c.regions.size() * sizeof(st_guide_region));
  take(c.nodes.data(), c.nodes.size() * sizeof(st_guide_node));
  take(c.pixel_estimate.data(), c.pixel_estimate.size() * sizeof(float));
  if (const std::string why = damage(c, cache.header); !why.empty()) throw fail(why);
  c.node_depth.assign(c.nodes.size(), 0);  // refinement's, host only: a read cache is not refined
  cache = std::move(c);
}

}  // namespace spectrack
