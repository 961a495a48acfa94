// nvdb_decode.h: NanoVDB density grids of double or quantized values (Fp4, Fp8, Fp16, FpN) read
// as the float grid the device reads (nvdb_decode.cpp has the design note), and the tree-layout
// check every NanoVDB grid passes first, float grids too (check_tree_layout).
#pragma once
#include <algorithm>
#include <cstdint>
#include <string>
#include <type_traits>

#include <nanovdb/NanoVDB.h>
#include <nanovdb/util/GridHandle.h>

#include "volume/volume_detail.h"

namespace spectrack {
namespace volume_detail {

// The tree's layout in a grid's bytes, checked as integers before a pointer is formed from the
// file's offsets and before NanoVDB's checksum and validator follow them: the root's offset
// (aligned, inside the buffer) and its tile table, which NanoVDB's partial checksum reads as if it
// followed the tree; every level's node-array offset inside the buffer (NanoVDB forms a level's
// first-node pointer even for an empty level); a non-empty level's nodes after the root's tile
// table, as NanoVDB lays them out, aligned, and where its nodes have one size (all but FpN leaves)
// the whole array inside the buffer, NanoVDB's checksum reading it as one, and FpN leaves no more
// than the smallest (1-bit) leaves its bytes hold; no level counting more nodes than 32-byte slots
// (a decoder's walk budget). Returns the root.
template <typename BuildT>
const nanovdb::NanoRoot<BuildT>& check_tree_layout(const nanovdb::NanoGrid<BuildT>& g, const Fail& fail) {
  using RootData = typename nanovdb::NanoRoot<BuildT>::DataType;
  auto corrupt = [&](const char* what) {
    fail(std::string("corrupt NanoVDB grid (") + what + " outside the grid, misaligned or inconsistent)");
  };
  const char* begin = reinterpret_cast<const char*>(&g);
  const int64_t size = int64_t(g.gridSize()), tree_at = sizeof(nanovdb::GridData);
  const auto* td = reinterpret_cast<const nanovdb::TreeData<3>*>(begin + tree_at);
  if (size < tree_at + int64_t(sizeof(*td))) corrupt("tree");
  const uint64_t off = td->mNodeOffset[3];
  const int64_t root_at = tree_at + int64_t(std::min<uint64_t>(off, uint64_t(size)));
  if (off >= uint64_t(size) || root_at % NANOVDB_DATA_ALIGNMENT || root_at > size - int64_t(sizeof(RootData)))
    corrupt("root");
  const auto* rd = reinterpret_cast<const RootData*>(begin + root_at);
  const uint64_t tiles = rd->mTableSize, tile_size = sizeof(typename RootData::Tile);
  if (tiles > uint64_t(size - root_at) / tile_size || int64_t(sizeof(*rd) + tiles * tile_size) > size - root_at)
    corrupt("root tile table");
  if (tree_at + int64_t(sizeof(*td) + sizeof(*rd) + tiles * tile_size) > size) corrupt("root tile table");
  const int64_t node_size[3] = {std::is_same_v<BuildT, nanovdb::FpN> ? 0 : int64_t(sizeof(nanovdb::NanoLeaf<BuildT>)),
                                int64_t(sizeof(nanovdb::NanoLower<BuildT>)), int64_t(sizeof(nanovdb::NanoUpper<BuildT>))};
  const uint64_t root_end = uint64_t(root_at - tree_at) + sizeof(*rd) + tiles * tile_size;
  for (int level = 0; level < 3; ++level) {
    const uint64_t n = td->mNodeCount[level], at = td->mNodeOffset[level];
    if (n > uint64_t(size) / 32) corrupt("node count");
    if (at > uint64_t(size - tree_at)) corrupt("node array");
    if (n == 0) continue;
    if (at < root_end || (tree_at + int64_t(at)) % NANOVDB_DATA_ALIGNMENT) corrupt("node array");
    if (node_size[level] > 0 && n > uint64_t(size - tree_at - int64_t(at)) / uint64_t(node_size[level]))
      corrupt("node array");
    if (node_size[level] == 0 &&  // FpN leaves: a header and at least 512 1-bit values each
        n > uint64_t(size - tree_at - int64_t(at)) / uint64_t(sizeof(typename nanovdb::NanoLeaf<BuildT>::DataType) + 64))
      corrupt("node count");
  }
  return *reinterpret_cast<const nanovdb::NanoRoot<BuildT>*>(rd);
}

// Whether nvdb_decode reads grids of this value type.
bool nvdb_decodable(nanovdb::GridType t);
// The untrusted grid in src (its header checked by nvdb_read) validated and decoded into a float
// grid; throws through fail where it is damaged or a value cannot be a float.
nanovdb::GridHandle<nanovdb::HostBuffer> nvdb_decode(const nanovdb::GridHandle<nanovdb::HostBuffer>& src, const Entry& e,
                                                     const Fail& fail);

}  // namespace volume_detail
}  // namespace spectrack
