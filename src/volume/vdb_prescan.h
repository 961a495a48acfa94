// vdb_prescan.h: internal to src/volume: the structural walk of a .vdb file that runs before
// OpenVDB reads it (vdb_prescan.cpp): the header, metadata and grid descriptors of the whole
// file, and the tree data (topology and buffers) of each grid before that grid is read.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "volume/volume_detail.h"

namespace spectrack {
namespace volume_detail {

// One grid descriptor of a .vdb file: where its data lies and what its tree holds.
struct VdbGridSpan {
  std::string unique_name;      // the descriptor's name (io::File::readGrid's key)
  std::string parent;           // instance parent's unique name ("" when the grid has its own tree)
  std::string tree_type;        // e.g. Tree_float_5_4_3 (without the _HalfFloat suffix)
  bool half = false;            // values written as half floats
  uint64_t grid_pos = 0, block_pos = 0, end_pos = 0;
};

struct VdbLayout {
  uint32_t version = 0;               // file format version
  bool has_offsets = false;           // descriptors carry grid offsets (io::File, not io::Stream)
  std::vector<VdbGridSpan> grids;
};

// Walks the header, file metadata, grid descriptors and each grid's metadata, checking every
// length and offset against the file size (throws through fail).
VdbLayout prescan_vdb(const std::string& file, const Fail& fail);

// Whether the tree of grid `g` is of a type the walk below can check (scalar and vec3 grids of
// float, double, int32 and int64 values with the standard 5-4-3 tree).
bool vdb_tree_checkable(const VdbGridSpan& g);

// Walks the tree data of grid `unique_name` (its instance parent's for an instance): every node
// mask, tile count, child origin and compressed chunk (zip, blosc or raw) against the sizes
// OpenVDB will read it into, so OpenVDB reads only data it can hold. Fails with the grid, the
// byte offset and the reason for damage, and for trees it cannot check.
void check_vdb_tree(const std::string& file, const VdbLayout& layout, const std::string& unique_name, const Fail& fail);

}  // namespace volume_detail
}  // namespace spectrack
