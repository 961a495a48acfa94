// volume_detail.h: what the loaders of volume.cpp and nvdb_file.cpp share (internal to
// src/volume): NanoVDB type names, the Fail message builder, and the grid list entry.
#pragma once
#include <algorithm>
#include <array>
#include <cstdint>
#include <sstream>
#include <string>
#include <vector>

#include <nanovdb/NanoVDB.h>
#include <nanovdb/util/GridHandle.h>

#include "util/error.h"

namespace spectrack {

struct GridData;  // volume.h

// Moves the kept grid (volume.h KeptGrids) of (file, grid_name, grid_index) into *out and forgets
// it; false where none is kept (kept_grids.cpp). load_float_grid asks it first.
bool take_kept_grid(const std::string& file, const std::string& grid_name, int grid_index, GridData* out);

struct GridData;  // volume.h

namespace volume_detail {

using FloatGrid = nanovdb::NanoGrid<float>;
using Root = nanovdb::NanoRoot<float>;
using Upper = nanovdb::NanoUpper<float>;
using Lower = nanovdb::NanoLower<float>;
using Leaf = nanovdb::NanoLeaf<float>;

// Calls f(value) for the voxels lo .. hi (inclusive) of a NanoVDB grid through its accessor: each
// 8^3 leaf-aligned block that meets the box gives a leaf's voxels inside the box, or the block's
// one value (a tile's or the background) once. The bounds of a box cost what its leaves hold.
template <typename Accessor, typename F>
void for_each_box_value(Accessor& acc, const std::array<int, 3>& lo, const std::array<int, 3>& hi, F&& f) {
  for (int bz = lo[2] & ~7; bz <= hi[2]; bz += 8)
    for (int by = lo[1] & ~7; by <= hi[1]; by += 8)
      for (int bx = lo[0] & ~7; bx <= hi[0]; bx += 8) {
        const nanovdb::Coord block(bx, by, bz);
        const auto* leaf = acc.probeLeaf(block);
        if (!leaf) {
          f(acc.getValue(block));
          continue;
        }
        for (int z = std::max(lo[2], bz); z <= std::min(hi[2], bz + 7); ++z)
          for (int y = std::max(lo[1], by); y <= std::min(hi[1], by + 7); ++y)
            for (int x = std::max(lo[0], bx); x <= std::min(hi[0], bx + 7); ++x) f(leaf->getValue(nanovdb::Coord(x, y, z)));
      }
}

// Formats "<context>: <file>: <reason>" and throws.
struct Fail {
  std::string context, file;
  [[noreturn]] void operator()(const std::string& reason) const {
    std::string msg = context.empty() ? file : context + ": " + file;
    throw Error(msg + ": " + reason);
  }
};

inline std::string coord_str(int x, int y, int z) {
  std::ostringstream s;
  s << "(" << x << ", " << y << ", " << z << ")";
  return s.str();
}

// A name from a file as it is printed: control characters (and backslash, quote) escaped, so a
// name cannot move the terminal's cursor or forge a line of output.
inline std::string printable(const std::string& s) {
  static const char* hex = "0123456789abcdef";
  std::string out;
  for (unsigned char c : s) {
    if (c == '\\' || c == '"') out += '\\', out += char(c);
    else if (c < 0x20 || c == 0x7f) out += "\\x", out += hex[c >> 4], out += hex[c & 15];
    else out += char(c);
  }
  return out;
}

inline std::string in_quotes(const std::string& s) { return "\"" + printable(s) + "\""; }

// One grid of a file, as listed before its tree is read.
struct Entry {
  std::string name;   // grid name ("" for unnamed)
  std::string type;   // value type: float, int32, vec3s / Vec3f, ...
  std::string cls;    // grid class in OpenVDB's words
  bool is_float = false;
  bool level_set = false;
  std::string vdb_key;          // .vdb: unique name for io::File::readGrid
  uint64_t nv_offset = 0;       // .nvdb: byte offset of the (possibly compressed) grid data
  uint64_t nv_grid_size = 0, nv_file_size = 0;
  uint16_t nv_codec = 0;
};

inline std::string describe(const Entry& e) {
  return (e.name.empty() ? std::string("<unnamed>") : printable(e.name)) + " (" + printable(e.type) + ", " + e.cls + ")";
}

// .nvdb files (nvdb_file.cpp): the grids of a file, every size checked against the file length;
// and one grid read (decompressed, validated; double and quantized grids decoded into float ones,
// nvdb_decode.h) into a handle.
std::vector<Entry> nvdb_entries(const std::string& file, const Fail& fail);
nanovdb::GridHandle<nanovdb::HostBuffer> nvdb_read(const std::string& file, const Entry& e, const Fail& fail);
// The grid's bytes with only its header checked (magic, size, index): enough for its metadata
// (GridHandle::gridMetaData) whatever its value type, nothing that follows an offset.
nanovdb::GridHandle<nanovdb::HostBuffer> nvdb_read_raw(const std::string& file, const Entry& e, const Fail& fail);
// The index bbox a raw grid stores (its root's), after the root's offset is checked.
nanovdb::CoordBBox nvdb_index_bbox(const nanovdb::GridHandle<nanovdb::HostBuffer>& h, const Fail& fail);

// A float as the messages print it (9 significant digits: reads back as the same float).
std::string value_str(float v);
// Fills a GridData from its NanoVDB float grid after the tree checks (grid_checks.cpp); throws
// through fail for level sets, non-zero backgrounds, degenerate maps and negative or non-finite
// active values. untrusted: the tree came from a file's bytes (.nvdb), so its pointers are
// validated first.
void finish_grid(GridData& out, const Fail& fail, bool untrusted);

}  // namespace volume_detail
}  // namespace spectrack
