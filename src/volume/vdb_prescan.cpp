// vdb_prescan.cpp: the structural walk of .vdb files (vdb_prescan.h).
//
// Design: OpenVDB's reader trusts the file. It allocates every length-prefixed string and
// metadata blob before reading it, loops over root tile and child counts as stored, reads an
// uncompressed chunk of the size the file claims into a node buffer of fixed size, and hands a
// blosc chunk whose header claims more bytes than the chunk holds to blosc, which reads past it:
// one flipped bit then aborts the process. So before OpenVDB sees a file, the walk here reads
// the same bytes in the same order as OpenVDB's readGrid (compression flags, metadata, transform,
// Tree::readTopology, Tree::readBuffers, io::readCompressedValues and its zip, blosc and raw
// chunks), without decompressing anything, and checks each count, mask, origin and chunk size
// against the file and against what the node it fills can hold. Only what it checked reaches
// OpenVDB; trees of types it cannot walk, and files of layouts it does not know, are refused.
#include "volume/vdb_prescan.h"

#include <algorithm>
#include <array>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>

#include <openvdb/io/Compression.h>
#include <openvdb/io/GridDescriptor.h>
#include <openvdb/openvdb.h>

namespace spectrack {
namespace volume_detail {
namespace {

namespace fs = std::filesystem;

// Bounds-checked reads over [pos, limit) of a file.
struct Reader {
  std::ifstream is;
  uint64_t size = 0, pos = 0, limit = 0;
  const Fail& fail;
  std::string where;  // prefix for messages ("corrupt grid "density": ")
  Reader(const std::string& file, const Fail& f) : is(file, std::ios::binary), size(fs::file_size(file)), limit(size), fail(f) {}
  [[noreturn]] void corrupt(const std::string& why) const {
    fail("corrupt or truncated OpenVDB file: " + where + why + " (at byte " + std::to_string(pos) + ")");
  }
  void need(uint64_t n, const char* what) {
    if (n > limit - pos) corrupt(std::string(what) + " runs past the end of its data");
  }
  template <class T>
  T get(const char* what) {
    need(sizeof(T), what);
    T v{};
    is.read(reinterpret_cast<char*>(&v), sizeof(T));
    pos += sizeof(T);
    return v;
  }
  void bytes(void* out, uint64_t n, const char* what) {
    need(n, what);
    is.read(static_cast<char*>(out), std::streamsize(n));
    pos += n;
  }
  void skip(uint64_t n, const char* what) {
    need(n, what);
    seek(pos + n);
  }
  std::string string(const char* what) {
    const uint32_t n = get<uint32_t>(what);
    need(n, what);
    std::string s(n, '\0');
    bytes(s.data(), n, what);
    return s;
  }
  void seek(uint64_t p) {
    pos = p;
    is.seekg(std::streamoff(p));
  }
};

// OpenVDB reads a metadata value of a fixed-size type as that many bytes, whatever size the file
// gives it, so a size that disagrees would leave the walk and OpenVDB at different bytes.
uint32_t fixed_metadata_size(const std::string& type) {
  static const std::map<std::string, uint32_t> sizes = {
      {"bool", 1}, {"int32", 4}, {"int64", 8}, {"float", 4}, {"double", 8}, {"vec2i", 8}, {"vec2s", 8},
      {"vec2d", 16}, {"vec3i", 12}, {"vec3s", 12}, {"vec3d", 24}, {"vec4i", 16}, {"vec4s", 16}, {"vec4d", 32},
      {"mat4s", 64}, {"mat4d", 128}};
  auto it = sizes.find(type);
  return it == sizes.end() ? 0 : it->second;
}

// The blosc header (version, versionlz, flags, typesize, nbytes, blocksize, cbytes; little
// endian): blosc trusts cbytes and nbytes, so both must match what OpenVDB gives it.
struct BloscHeader {
  uint8_t version;
  uint32_t nbytes, blocksize, cbytes;
};
BloscHeader read_blosc_header(Reader& r) {
  unsigned char h[16];
  r.bytes(h, 16, "blosc header");
  auto le32 = [&](int at) { return uint32_t(h[at]) | uint32_t(h[at + 1]) << 8 | uint32_t(h[at + 2]) << 16 | uint32_t(h[at + 3]) << 24; };
  return {h[0], le32(4), le32(8), le32(12)};
}

// DelayedLoadMetadata::readValue: a count of the grid's leaves, then two arrays of that many
// entries (a 1-byte mask each, an 8-byte compressed size each; the second may be absent, a size of
// 0xffffffff), each stored raw (a stored size of 0) or as one blosc chunk of the stored size.
// OpenVDB sizes both arrays by the count and allocates each chunk by its stored size before it
// reads them, and it reads all of it whatever the value's size says, so every part must lie in the
// value: a count beyond what the file can hold, a chunk larger than the value or one that decodes
// to more than its array (padded to 128 bytes) would allocate gigabytes or misread the stream.
void check_delayed_load(Reader& r, uint32_t size) {
  const uint64_t outer = r.limit;
  r.limit = r.pos + size;  // every read below must stay inside the value
  const uint32_t n = r.get<uint32_t>("delayed-load count");
  // every leaf stores its 64-byte value mask in the file
  if (n > r.size / 64)
    r.corrupt("delayed-load metadata claims " + std::to_string(n) + " leaves, more than a " + std::to_string(r.size) +
              "-byte file can hold (64 bytes a leaf)");
  auto array = [&](uint64_t raw, const char* what) {
    const uint32_t stored = r.get<uint32_t>(what);
    if (stored == 0) return r.skip(raw, what);
    if (stored < 16 || stored > r.limit - r.pos)
      r.corrupt(std::string(what) + ": a blosc chunk of " + std::to_string(stored) + " bytes in a metadata value of " +
                std::to_string(size));
    const BloscHeader h = read_blosc_header(r);
    // OpenVDB pads an array of fewer than 128 bytes to 128 before it compresses it (BLOSC_PAD_BYTES)
    if (h.cbytes != stored || h.nbytes < raw || h.nbytes > std::max<uint64_t>(raw, 128))
      r.corrupt(std::string(what) + ": its blosc chunk claims " + std::to_string(h.cbytes) + " compressed and " +
                std::to_string(h.nbytes) + " decoded bytes where it has " + std::to_string(stored) + " and the array " +
                std::to_string(raw));
    r.skip(uint64_t(stored) - 16, what);
  };
  array(uint64_t(n), "delayed-load masks");
  const uint64_t at = r.pos;
  if (r.get<uint32_t>("delayed-load sizes") != 0xffffffffu) {  // else no sizes are stored
    r.seek(at);
    array(uint64_t(n) * 8, "delayed-load sizes");
  }
  r.skip(r.limit - r.pos, "metadata value");  // what a later version adds, which OpenVDB skips
  r.limit = outer;
}

void skip_metamap(Reader& r) {
  const uint32_t count = r.get<uint32_t>("metadata count");
  if (count > (r.limit - r.pos) / 12) r.corrupt("implausible metadata count " + std::to_string(count));
  for (uint32_t i = 0; i < count; ++i) {
    r.skip(r.get<uint32_t>("metadata name"), "metadata name");
    const std::string type = r.string("metadata type");
    const uint32_t size = r.get<uint32_t>("metadata value"), fixed = fixed_metadata_size(type);
    if (fixed != 0 && size != fixed)
      r.corrupt("a " + printable(type) + " metadata value of " + std::to_string(size) + " bytes (it has " + std::to_string(fixed) + ")");
    if (type == "__delayedload" && size > 0) {
      check_delayed_load(r, size);
      continue;
    }
    r.skip(size, "metadata value");
  }
}

// ---- tree walk --------------------------------------------------------------------------------

// How a grid's values are stored: value size, half-float size, compression flags.
struct Values {
  uint32_t size = 4, half_size = 2;
  bool half = false;
  uint32_t compression = 0;
};

using Mask = std::vector<uint64_t>;

size_t count_on(const Mask& m) {
  size_t n = 0;
  for (uint64_t w : m) n += size_t(__builtin_popcountll(w));
  return n;
}

Mask read_mask(Reader& r, uint32_t log2dim, const char* what) {
  Mask m(size_t(1) << (3 * log2dim - 6));
  r.bytes(m.data(), m.size() * 8, what);
  return m;
}

// One chunk of `bytes` decoded bytes as io::readData reads it: blosc, else zip, else raw.
void check_chunk(Reader& r, const Values& v, uint64_t bytes) {
  using namespace openvdb::io;
  if (!(v.compression & (COMPRESS_BLOSC | COMPRESS_ZIP))) return r.skip(bytes, "uncompressed values");
  const char* kind = v.compression & COMPRESS_BLOSC ? "blosc" : "zip";
  const int64_t n = r.get<int64_t>("chunk size");
  if (n <= 0) {
    if (uint64_t(-n) != bytes) {
      r.corrupt(std::string("uncompressed ") + kind + " chunk of " + std::to_string(-n) + " bytes where the node holds " +
                std::to_string(bytes));
    }
    return r.skip(bytes, "uncompressed chunk");
  }
  if (uint64_t(n) > r.limit - r.pos) r.corrupt(std::string(kind) + " chunk of " + std::to_string(n) + " bytes runs past the end of its data");
  if (v.compression & COMPRESS_BLOSC) {
    if (n < 16) r.corrupt("blosc chunk of " + std::to_string(n) + " bytes is shorter than its header");
    const auto [version, nbytes, blocksize, cbytes] = read_blosc_header(r);
    if (cbytes != uint64_t(n) || nbytes != bytes || version > 2 || (nbytes > 0 && blocksize == 0)) {
      r.corrupt("blosc chunk header claims " + std::to_string(cbytes) + " compressed and " + std::to_string(nbytes) +
                " decoded bytes where the chunk has " + std::to_string(n) + " and the node holds " + std::to_string(bytes));
    }
    return r.skip(uint64_t(n) - 16, "blosc chunk");
  }
  r.skip(uint64_t(n), "zip chunk");
}

// io::readCompressedValues for a node of `count` values whose active mask is `active`.
void check_values(Reader& r, const Values& v, uint64_t count, const Mask& active, uint32_t log2dim) {
  const int8_t meta = r.get<int8_t>("node compression metadata");
  if (meta < 0 || meta > 6) r.corrupt("unknown node compression metadata " + std::to_string(int(meta)));
  if (meta == 2 || meta == 4 || meta == 5) r.skip(v.size, "inactive value");  // one inactive value
  if (meta == 5) r.skip(v.size, "inactive value");                             // and a second
  if (meta >= 3 && meta <= 5) r.skip(uint64_t(1) << (3 * log2dim - 3), "selection mask");
  const bool masked = (v.compression & openvdb::io::COMPRESS_ACTIVE_MASK) && meta != 6;
  const uint64_t n = masked ? count_on(active) : count;
  if (v.half && n < 1) return;  // HalfReader reads nothing
  check_chunk(r, v, n * (v.half ? v.half_size : v.size));
}

struct Walk {
  Reader& r;
  Values v;
  std::vector<Mask> leaves;  // the leaves' topology masks, in topology order
};

// InternalNode::readTopology: child and value masks, tile values, then each child.
void check_internal(Walk& w, uint32_t log2dim) {
  const Mask child = read_mask(w.r, log2dim, "child mask");
  const Mask value = read_mask(w.r, log2dim, "value mask");
  check_values(w.r, w.v, uint64_t(1) << (3 * log2dim), value, log2dim);
  // each child holds at least its two masks (a leaf: one)
  const uint64_t least = log2dim == 5 ? 2 * 512 + 1 : 64;
  if (count_on(child) > (w.r.limit - w.r.pos) / least) w.r.corrupt("more child nodes than the data can hold");
  for (size_t i = 0; i < child.size(); ++i)
    for (uint64_t bits = child[i]; bits; bits &= bits - 1) {
      if (log2dim == 5) check_internal(w, 4);
      else w.leaves.push_back(read_mask(w.r, 3, "leaf value mask"));
    }
}

// RootNode::readTopology up to the descriptor's block position, then Tree::readBuffers over the
// leaves in the root's (sorted) order up to the grid's end.
void check_root(Walk& w, uint64_t block_pos, uint64_t end_pos) {
  Reader& r = w.r;
  r.get<int32_t>("buffer count");
  r.skip(w.v.size, "background value");
  const uint32_t tiles = r.get<uint32_t>("root tile count"), children = r.get<uint32_t>("root child count");
  const uint64_t tile_bytes = 12 + w.v.size + 1;
  if (tiles > (r.limit - r.pos) / tile_bytes) r.corrupt("root tile count " + std::to_string(tiles) + " exceeds the data");
  if (children > (r.limit - r.pos) / (12 + 2 * 4096)) r.corrupt("root child count " + std::to_string(children) + " exceeds the data");
  std::map<std::array<int32_t, 3>, size_t> keys;  // origin -> child index (tiles: SIZE_MAX)
  auto origin = [&](bool is_child) {
    std::array<int32_t, 3> o;
    r.bytes(o.data(), 12, "root entry origin");
    for (int32_t c : o)
      if (c & 4095) r.corrupt("root entry origin is not a multiple of 4096");
    if (!keys.emplace(o, is_child ? keys.size() : SIZE_MAX).second) r.corrupt("two root entries at one origin");
  };
  for (uint32_t i = 0; i < tiles; ++i) {
    origin(false);
    r.skip(w.v.size + 1, "root tile");
  }
  std::vector<std::pair<size_t, size_t>> spans;  // each child's leaves [first, end)
  for (uint32_t i = 0; i < children; ++i) {
    origin(true);
    const size_t first = w.leaves.size();
    check_internal(w, 5);
    spans.emplace_back(first, w.leaves.size());
  }
  if (r.pos != block_pos) r.corrupt("the tree topology ends " + std::to_string(int64_t(block_pos) - int64_t(r.pos)) + " bytes before its buffers");
  r.limit = end_pos;
  std::vector<size_t> order;  // the buffers follow the root's map, sorted by origin
  for (const auto& [o, index] : keys)
    if (index != SIZE_MAX) order.push_back(index - tiles);
  for (size_t c : order)
    for (size_t l = spans[c].first; l < spans[c].second; ++l) {
      const Mask m = read_mask(r, 3, "leaf value mask");
      if (m != w.leaves[l]) r.corrupt("a leaf's value mask differs between topology and buffers");
      check_values(r, w.v, 512, m, 3);
    }
}

// Transform::read: the map type, then the map's own fields.
void skip_map(Reader& r, const std::string& type, uint32_t version, int depth) {
  if (type == "AffineMap" || type == "UnitaryMap") return r.skip(128, "transform");
  if (type == "ScaleMap" || type == "UniformScaleMap") return r.skip(5 * 24, "transform");
  if (type == "TranslationMap") return r.skip(24, "transform");
  if (type == "ScaleTranslateMap" || type == "UniformScaleTranslateMap") return r.skip(6 * 24, "transform");
  if (type == "NonlinearFrustumMap" && depth == 0) {
    r.skip(version < openvdb::OPENVDB_FILE_VERSION_FLOAT_FRUSTUM_BBOX ? 24 : 48, "frustum box");
    r.skip(16, "frustum taper and depth");
    return skip_map(r, r.string("frustum map type"), version, 1);
  }
  r.corrupt("unknown transform map type \"" + type + "\"");
}

bool value_sizes(const std::string& tree_type, Values& v) {
  static const std::map<std::string, std::array<uint32_t, 3>> sizes = {  // size, half size, real
      {"Tree_float_5_4_3", {4, 2, 1}}, {"Tree_double_5_4_3", {8, 2, 1}}, {"Tree_int32_5_4_3", {4, 4, 0}},
      {"Tree_int64_5_4_3", {8, 8, 0}}, {"Tree_vec3s_5_4_3", {12, 6, 1}}, {"Tree_vec3d_5_4_3", {24, 6, 1}},
      {"Tree_vec3i_5_4_3", {12, 12, 0}}};
  auto it = sizes.find(tree_type);
  if (it == sizes.end()) return false;
  v.size = it->second[0];
  v.half_size = it->second[1];
  v.half = v.half && it->second[2];  // HalfReader converts real types only
  return true;
}

}  // namespace

VdbLayout prescan_vdb(const std::string& file, const Fail& fail) {
  VdbLayout out;
  Reader r(file, fail);
  if (r.get<int64_t>("magic number") != openvdb::OPENVDB_MAGIC) fail("not an OpenVDB file (bad magic number)");
  out.version = r.get<uint32_t>("file version");
  if (out.version < openvdb::OPENVDB_FILE_VERSION_NODE_MASK_COMPRESSION) {
    fail("OpenVDB file format version " + std::to_string(out.version) +
         " predates 222 (2013) and cannot be checked before reading; re-save the file with a current OpenVDB");
  }
  r.skip(8, "library version");
  out.has_offsets = r.get<char>("header") != 0;
  r.skip(36, "file UUID");
  skip_metamap(r);
  if (!out.has_offsets) {
    fail("OpenVDB stream without grid offsets: it cannot be checked before reading; re-save it as a file "
         "with a current OpenVDB");
  }
  const int32_t count = r.get<int32_t>("grid count");
  if (count < 0 || uint64_t(count) > (r.size - r.pos) / 36 + 1) r.corrupt("implausible grid count " + std::to_string(count));
  for (int32_t i = 0; i < count; ++i) {
    VdbGridSpan g;
    g.unique_name = r.string("grid name");
    g.tree_type = r.string("grid type");
    const std::string suffix = "_HalfFloat";
    if (g.tree_type.size() > suffix.size() && g.tree_type.compare(g.tree_type.size() - suffix.size(), suffix.size(), suffix) == 0) {
      g.half = true;
      g.tree_type.resize(g.tree_type.size() - suffix.size());
    }
    g.parent = r.string("instance parent name");
    const int64_t a = r.get<int64_t>("grid offset"), b = r.get<int64_t>("grid offset"), e = r.get<int64_t>("grid offset");
    if (a < int64_t(r.pos) || a > b || b > e || uint64_t(e) > r.size) r.corrupt("grid offsets outside the file");
    g.grid_pos = uint64_t(a), g.block_pos = uint64_t(b), g.end_pos = uint64_t(e);
    out.grids.push_back(g);
    r.seek(g.end_pos);  // each descriptor is followed by its grid's data
  }
  for (const VdbGridSpan& g : out.grids) {
    r.seek(g.grid_pos);
    r.skip(4, "grid compression flags");
    skip_metamap(r);
    r.skip(r.get<uint32_t>("transform type"), "transform type");
  }
  return out;
}

bool vdb_tree_checkable(const VdbGridSpan& g) {
  Values v;
  return value_sizes(g.tree_type, v);
}

void check_vdb_tree(const std::string& file, const VdbLayout& layout, const std::string& unique_name, const Fail& fail) {
  if (layout.version < openvdb::OPENVDB_FILE_VERSION_NODE_MASK_COMPRESSION || !layout.has_offsets) {
    fail("OpenVDB file format version " + std::to_string(layout.version) +
         (layout.has_offsets ? "" : " without grid offsets (a stream)") +
         " cannot be checked before reading; re-save the file with a current OpenVDB");
  }
  auto find = [&](const std::string& name) -> const VdbGridSpan* {
    for (const VdbGridSpan& g : layout.grids)
      if (g.unique_name == name) return &g;
    return nullptr;
  };
  // io::File names a duplicate "name[1]"; its descriptor holds "name\x1e1"
  const VdbGridSpan* g = find(openvdb::io::GridDescriptor::stringAsUniqueName(unique_name));
  if (g && !g->parent.empty()) g = find(g->parent);
  if (!g) fail("grid " + in_quotes(unique_name) + " (or its instance parent) is not in the file's grid list");
  Values v;
  v.half = g->half;
  if (!value_sizes(g->tree_type, v)) {
    fail("grid " + in_quotes(unique_name) + " has tree type " + in_quotes(g->tree_type) +
         ", whose data spectrack cannot check before reading");
  }
  Reader r(file, fail);
  r.where = "grid " + in_quotes(openvdb::io::GridDescriptor::nameAsString(g->unique_name)) + ": ";
  r.limit = g->end_pos;
  r.seek(g->grid_pos);
  v.compression = r.get<uint32_t>("grid compression flags");
  skip_metamap(r);
  skip_map(r, r.string("transform type"), layout.version, 0);
  r.limit = g->block_pos;  // the topology, then (check_root) the buffers
  Walk w{r, v, {}};
  check_root(w, g->block_pos, g->end_pos);
  if (r.pos != g->end_pos) r.corrupt("the tree ends " + std::to_string(int64_t(g->end_pos) - int64_t(r.pos)) + " bytes before its grid's end");
}

}  // namespace volume_detail
}  // namespace spectrack
