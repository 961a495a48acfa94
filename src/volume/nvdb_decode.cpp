// nvdb_decode.cpp: NanoVDB density grids of other value types than float, read as the float grid
// the device reads. NanoVDB writes double grids and four quantized kinds (Fp4, Fp8 and Fp16: every
// leaf's values as 4-, 8- or 16-bit codes between the leaf's minimum and maximum; FpN: a bit width
// of 1 to 16 chosen per leaf, `nanovdb_convert --fpN`, as Blender and VisRTX store grids to save
// GPU memory). Such a grid's bytes come from a file and are untrusted, as a float grid's are
// (nvdb_file.cpp): one walk from the root checks every child offset (as an integer, before a
// pointer is formed), each FpN leaf's bit width and extent, and that each level holds exactly the
// node count the tree stores (NanoVDB's checksum and validator size their node tables by those
// counts and would write past them otherwise; the counts also bound the walk where slots share a
// child). Only then does NanoVDB's validator run (its checksum, full where the writer stored one),
// and the walk's active voxels must match the count the grid stores. The same walk decodes every
// active voxel and tile at its place in the tree (the slots, never a stored origin) into an
// OpenVDB float tree, which becomes the NanoVDB float grid every other grid is (so the checks of
// grid_checks.cpp, the majorant grids and the kernels see one type). A double value beyond a
// float's range is refused naming it, as for OpenVDB double grids (volume.cpp to_float_grid). The
// decoded grid's memory, estimated from the stored node counts, is checked against the host's
// before any node is decoded.
#include "volume/nvdb_decode.h"

#include <openvdb/openvdb.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>
#include <set>
#include <type_traits>
#include <vector>

#include <nanovdb/util/GridValidator.h>
#include <nanovdb/util/OpenToNanoVDB.h>

#include "util/host_memory.h"

namespace spectrack {
namespace volume_detail {
namespace {

template <typename BuildT>
class Decoder {
  using GridT = nanovdb::NanoGrid<BuildT>;
  using RootT = nanovdb::NanoRoot<BuildT>;
  using UpperT = nanovdb::NanoUpper<BuildT>;
  using LowerT = nanovdb::NanoLower<BuildT>;
  using LeafT = nanovdb::NanoLeaf<BuildT>;

 public:
  Decoder(const GridT& g, const std::string& name, const Fail& fail)
      : g_(g), name_(name), fail_(fail), begin_(reinterpret_cast<const char*>(&g)), size_(int64_t(g.gridSize())) {}

  openvdb::FloatGrid::Ptr run() {
    const RootT& root = check_tree_layout(g_, fail_);
    check_decoded_memory();
    if (root.background() != 0) {
      char bg[32];
      std::snprintf(bg, sizeof bg, "%.9g", double(root.background()));
      fail_("grid " + in_quotes(name_) + " has background value " + bg +
            "; inactive voxels must read 0 density (background must be 0)");
    }
    out_ = openvdb::FloatGrid::create(0.0f);
    acc_.emplace(out_->tree());
    std::set<std::array<int, 3>> keys;  // a key twice would decode two values at one place
    for (uint32_t i = 0; i < root.data()->mTableSize; ++i) {
      const auto* t = root.data()->tile(i);
      if (!keys.insert({t->origin()[0], t->origin()[1], t->origin()[2]}).second) corrupt("root key repeated");
      if (!t->isChild()) {
        if (t->isActive()) tile(3, t->origin(), t->value, UpperT::DIM);
        continue;
      }
      internal(*reinterpret_cast<const UpperT*>(child_at(root.data(), t->child, sizeof(UpperT), 2)), t->origin());
    }
    const auto* td = reinterpret_cast<const nanovdb::TreeData<3>*>(&g_.tree());
    for (int level = 0; level < 3; ++level)
      if (nodes_[level] != td->mNodeCount[level]) corrupt("node count");
    acc_.reset();
    const std::string why = nanovdb::GridValidator<BuildT>::check(g_, /*detailed=*/true);
    if (!why.empty()) fail_("corrupt NanoVDB grid " + in_quotes(name_) + ": " + why);
    if (voxels_ != g_.activeVoxelCount()) {
      fail_("corrupt NanoVDB grid " + in_quotes(name_) + ": its active voxels (" + std::to_string(voxels_) +
            ") disagree with the count stored in the grid (" + std::to_string(g_.activeVoxelCount()) + ")");
    }
    return out_;
  }

 private:
  [[noreturn]] void corrupt(const char* what) const {
    fail_(std::string("corrupt NanoVDB grid (") + what + " outside the grid, misaligned or inconsistent)");
  }

  // The decoded grid's memory, from the node counts check_tree_layout bounded, against the host's: an
  // OpenVDB float tree, then the NanoVDB float grid built from it (4.2 KiB a leaf: 27 times an FpN
  // leaf of 1-bit values, after a compressed file's own expansion of up to 1024 times).
  void check_decoded_memory() const {
    using OpenLeaf = openvdb::tree::LeafNode<float, 3>;
    using OpenLower = openvdb::tree::InternalNode<OpenLeaf, 4>;
    using OpenUpper = openvdb::tree::InternalNode<OpenLower, 5>;
    const auto* td = reinterpret_cast<const nanovdb::TreeData<3>*>(begin_ + sizeof(nanovdb::GridData));
    const double per_node[3] = {
        double(sizeof(OpenLeaf) + OpenLeaf::SIZE * sizeof(float) + sizeof(nanovdb::NanoLeaf<float>)),
        double(sizeof(OpenLower) + sizeof(nanovdb::NanoLower<float>)),
        double(sizeof(OpenUpper) + sizeof(nanovdb::NanoUpper<float>))};
    double bytes = 0;
    for (int level = 0; level < 3; ++level) bytes += double(td->mNodeCount[level]) * per_node[level];
    if (const std::string s = host_memory_shortfall(bytes); !s.empty())
      fail_("grid " + in_quotes(name_) + " (" + std::to_string(td->mNodeCount[0]) + " leaves) read as float " + s +
            "; free memory, or render on a machine with more");
  }

  // A child `off` bytes from its parent's data, of at least n bytes, counted at `level`.
  const char* child_at(const void* base, int64_t off, int64_t n, int level) {
    const int64_t at = int64_t(reinterpret_cast<const char*>(base) - begin_);
    if (off < -at || off > size_ - at - n || (at + off) % NANOVDB_DATA_ALIGNMENT != 0) corrupt("node pointer");
    const auto* td = reinterpret_cast<const nanovdb::TreeData<3>*>(&g_.tree());
    if (++nodes_[level] > td->mNodeCount[level]) corrupt("node count");
    // each node is reached once: slots sharing a child would decode it at every place they name
    const size_t slot = size_t(at + off) / NANOVDB_DATA_ALIGNMENT;
    if (seen_[slot]) corrupt("node pointer shared");
    seen_[slot] = true;
    return begin_ + (at + off);
  }

  // An upper or lower node at its place: active tiles, then each child (its offset checked).
  template <typename NodeT>
  void internal(const NodeT& node, const nanovdb::Coord& place) {
    using ChildT = typename NodeT::ChildNodeType;
    const auto* d = node.data();
    for (uint32_t n = 0; n < NodeT::SIZE; ++n) {
      const nanovdb::Coord p = child_origin<NodeT>(place, n);
      if (!d->isChild(n)) {
        if (d->isActive(n)) tile(ChildT::LEVEL + 1, p, d->mTable[n].value, ChildT::DIM);
        continue;
      }
      if constexpr (ChildT::LEVEL == 0) {
        leaf(*reinterpret_cast<const LeafT*>(child_at(d, d->mTable[n].child, leaf_header(), 0)), p);
      } else {
        internal(*reinterpret_cast<const ChildT*>(child_at(d, d->mTable[n].child, sizeof(ChildT), ChildT::LEVEL)), p);
      }
    }
  }

  static constexpr int64_t leaf_header() {
    if constexpr (std::is_same_v<BuildT, nanovdb::FpN>) return sizeof(typename LeafT::DataType);
    return sizeof(LeafT);
  }

  void leaf(const LeafT& leaf, const nanovdb::Coord& place) {
    if constexpr (std::is_same_v<BuildT, nanovdb::FpN>) {
      // 1, 2, 4, 8 or 16 bits per value follow the header (NanoVDB's bitWidth reads flags >> 5)
      const int64_t at = int64_t(reinterpret_cast<const char*>(&leaf) - begin_);
      if ((leaf.data()->mFlags >> 5) > 4 || int64_t(leaf.data()->memUsage()) > size_ - at) corrupt("FpN leaf");
    }
    if (leaf.valueMask().isOff()) return;
    openvdb::tree::LeafNode<float, 3>* out = acc_->touchLeaf(openvdb::Coord(place[0], place[1], place[2]));
    for (auto it = leaf.valueMask().beginOn(); it; ++it) {
      const uint32_t i = *it;
      const nanovdb::Coord c = place + LeafT::OffsetToLocalCoord(i);
      out->setValueOn(i, value(leaf.getValue(i), c, 1));
      ++voxels_;
    }
  }

  template <typename V>
  void tile(int level, const nanovdb::Coord& p, const V& v, int width) {
    out_->tree().addTile(level, openvdb::Coord(p[0], p[1], p[2]), value(v, p, width), true);
    acc_->clear();  // the tile may replace a node the accessor holds (a damaged file's duplicate slot)
    voxels_ += uint64_t(width) * uint64_t(width) * uint64_t(width);
  }

  // A value as a float; a double beyond a float's range is refused naming it.
  template <typename V>
  float value(const V& v, const nanovdb::Coord& p, int width) const {
    if constexpr (std::is_same_v<V, double>) {
      if (std::abs(v) > double(std::numeric_limits<float>::max())) {
        char s[32];
        std::snprintf(s, sizeof s, "%.9g", v);
        fail_("grid " + in_quotes(name_) + ": value " + s + " at " + (width == 1 ? "active voxel " : "active tile at ") +
              coord_str(p[0], p[1], p[2]) + " is beyond a 32-bit float's range (double grids are read as float)");
      }
    }
    return float(v);
  }

  template <typename Node>
  static nanovdb::Coord child_origin(const nanovdb::Coord& origin, uint32_t n) {
    nanovdb::Coord ijk = Node::OffsetToLocalCoord(n);
    ijk <<= Node::ChildNodeType::TOTAL;
    return ijk + origin;
  }

  const GridT& g_;
  const std::string& name_;
  const Fail& fail_;
  const char* begin_;
  int64_t size_;
  uint64_t nodes_[3] = {0, 0, 0};
  std::vector<bool> seen_ = std::vector<bool>(size_t(size_ / NANOVDB_DATA_ALIGNMENT) + 1);  // nodes reached, by 32-byte slot
  uint64_t voxels_ = 0;
  openvdb::FloatGrid::Ptr out_;
  std::optional<openvdb::FloatGrid::UnsafeAccessor> acc_;  // unregistered: TBB's accessor registry trips UBSan
};

// The grid's index-to-world map as OpenVDB's transform, refused where it is singular or not finite.
openvdb::math::Transform::Ptr transform_of(const nanovdb::Map& map, const std::string& name, const Fail& fail) {
  openvdb::math::Mat4d mat = openvdb::math::Mat4d::identity();
  // NanoVDB stores OpenVDB's 3x3 transposed (OpenToNanoVDB); transpose() returns the transpose
  // (NanoToOpenVDB's `mat.transpose();` discards it, so it maps rotated grids wrongly)
  mat.setMat3(openvdb::math::Mat3d(map.mMatD).transpose());
  mat.setTranslation(openvdb::math::Vec3d(map.mVecD));
  bool finite = true;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) finite = finite && std::isfinite(mat(r, c));
  const double det = mat.getMat3().det();
  if (!finite || !std::isfinite(det) || std::abs(det) < 1e-300)
    fail("grid " + in_quotes(name) + " has a singular or non-finite index-to-world transform");
  try {
    return openvdb::math::Transform::createLinearTransform(mat);
  } catch (const std::exception& ex) {
    fail("grid " + in_quotes(name) + " has an index-to-world transform OpenVDB refuses: " + ex.what());
  }
}

template <typename BuildT>
nanovdb::GridHandle<nanovdb::HostBuffer> decode(const nanovdb::GridHandle<nanovdb::HostBuffer>& src, const Entry& e,
                                                const Fail& fail) {
  const nanovdb::NanoGrid<BuildT>* g = src.grid<BuildT>();
  if (!g) fail("grid " + in_quotes(e.name) + " is not a " + e.type + " grid");
  openvdb::FloatGrid::Ptr grid = Decoder<BuildT>(*g, e.name, fail).run();
  grid->setName(e.name);
  grid->setGridClass(openvdb::GRID_FOG_VOLUME);
  grid->setTransform(transform_of(g->map(), e.name, fail));
  try {
    return nanovdb::openToNanoVDB(*grid);
  } catch (const std::exception& ex) {
    fail("cannot convert grid " + in_quotes(e.name) + " to a float NanoVDB grid: " + ex.what());
  }
}

}  // namespace

bool nvdb_decodable(nanovdb::GridType t) {
  using nanovdb::GridType;
  return t == GridType::Double || t == GridType::Fp4 || t == GridType::Fp8 || t == GridType::Fp16 ||
         t == GridType::FpN;
}

nanovdb::GridHandle<nanovdb::HostBuffer> nvdb_decode(const nanovdb::GridHandle<nanovdb::HostBuffer>& src, const Entry& e,
                                                     const Fail& fail) {
  const nanovdb::GridMetaData* m = src.gridMetaData();
  switch (m ? m->gridType() : nanovdb::GridType::Unknown) {
    case nanovdb::GridType::Double: return decode<double>(src, e, fail);
    case nanovdb::GridType::Fp4: return decode<nanovdb::Fp4>(src, e, fail);
    case nanovdb::GridType::Fp8: return decode<nanovdb::Fp8>(src, e, fail);
    case nanovdb::GridType::Fp16: return decode<nanovdb::Fp16>(src, e, fail);
    case nanovdb::GridType::FpN: return decode<nanovdb::FpN>(src, e, fail);
    default: fail("grid " + in_quotes(e.name) + " has value type " + e.type + ", which is not a density spectrack reads");
  }
}

}  // namespace volume_detail
}  // namespace spectrack
