// test_vdb_robustness.cpp: damaged and unusual volume files (src/volume): the tree pre-scan of
// .vdb files (vdb_prescan.cpp) against damaged chunks and flipped bits, inactive values that must
// read 0, the sparse majorant build over far-apart voxels, and what `info` prints and refuses.
// Every damaged file is made here from one written by OpenVDB (or from a shared file, copied into
// memory and written to a temporary folder).
#include <gtest/gtest.h>

#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>

#include <openvdb/io/Compression.h>
#include <openvdb/openvdb.h>

#include <nanovdb/util/IO.h>
#include <nanovdb/util/OpenToNanoVDB.h>

#include "volume/float_limits.h"
#include "volume/inspect.h"
#include "volume/volume.h"
#include "test_util.h"

namespace fs = std::filesystem;
using spectrack::GridData;
using spectrack::MajorantGrid;
using st_test::error_of;

namespace {

struct TempDir {
  fs::path dir;
  TempDir() {
    dir = fs::temp_directory_path() / ("spectrack_test_vdb_robust_" + std::to_string(::getpid()));
    fs::create_directories(dir);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
  std::string file(const std::string& name) const { return (dir / name).string(); }
};

bool contains(const std::string& s, const std::string& sub) { return s.find(sub) != std::string::npos; }

std::string read_bytes(const std::string& path) {
  std::ifstream is(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(is), {});
}
void write_bytes(const std::string& path, const std::string& b) { std::ofstream(path, std::ios::binary) << b; }

openvdb::FloatGrid::Ptr blob(const std::string& name = "density") {
  openvdb::initialize();
  auto g = openvdb::FloatGrid::create(0.0f);
  g->setName(name);
  g->setGridClass(openvdb::GRID_FOG_VOLUME);
  auto acc = g->getAccessor();
  for (int z = 0; z < 20; ++z)
    for (int y = 0; y < 20; ++y)
      for (int x = 0; x < 20; ++x) {
        const float d = std::sqrt(float((x - 10) * (x - 10) + (y - 10) * (y - 10) + (z - 10) * (z - 10)));
        if (d < 9.0f) acc.setValue({x, y, z}, 1.0f - d / 9.0f + 0.01f * float((x * 7 + y * 3 + z) % 5));
      }
  return g;
}

void write_vdb(const std::string& path, openvdb::GridBase::Ptr g, uint32_t compression) {
  openvdb::io::File f(path);
  f.setCompression(compression);
  f.write({g});
  f.close();
}

// Loads the file; true when it loaded, false when it was refused with an Error naming the file.
// Anything else (a crash, another exception) fails the test.
bool loads_or_refuses(const std::string& path) {
  try {
    spectrack::load_float_grid(path, "density", -1, "test");
    return true;
  } catch (const spectrack::Error& e) {
    EXPECT_TRUE(contains(e.what(), path)) << e.what();
    return false;
  }
}

// The offset of the first blosc chunk (its int64 size, then a header whose cbytes equals it).
size_t first_blosc_chunk(const std::string& b) {
  for (size_t p = 0; p + 24 <= b.size(); ++p) {
    int64_t n;
    uint32_t cbytes, nbytes;
    std::memcpy(&n, &b[p], 8);
    std::memcpy(&nbytes, &b[p + 12], 4);
    std::memcpy(&cbytes, &b[p + 20], 4);
    if (n > 16 && int64_t(cbytes) == n && nbytes > 0 && nbytes <= 512 * 4 && b[p + 8] == 2) return p;
  }
  return std::string::npos;
}

}  // namespace

// ---- the tree pre-scan ------------------------------------------------------------------------

TEST(VolumePrescan, BloscChunkLargerThanItsDataIsRefused) {
  TempDir d;
  const std::string src = d.file("blosc.vdb");
  write_vdb(src, blob(), openvdb::io::COMPRESS_BLOSC | openvdb::io::COMPRESS_ACTIVE_MASK);
  ASSERT_TRUE(loads_or_refuses(src));
  const std::string bytes = read_bytes(src);
  const size_t at = first_blosc_chunk(bytes);
  ASSERT_NE(at, std::string::npos);
  struct Case { size_t off; int64_t value; int width; const char* why; };
  int64_t n;
  std::memcpy(&n, &bytes[at], 8);
  for (const Case& c : {Case{at + 20, n + 4096, 4, "blosc chunk header claims"},      // cbytes past the chunk
                        Case{at + 12, 1 << 20, 4, "blosc chunk header claims"},        // nbytes past the node
                        Case{at, -(1 << 20), 8, "uncompressed blosc chunk of"},        // raw chunk past the node
                        Case{at, int64_t(1) << 40, 8, "runs past the end"}}) {        // chunk past the file
    std::string bad = bytes;
    std::memcpy(&bad[c.off], &c.value, size_t(c.width));
    const std::string path = d.file("bad.vdb");
    write_bytes(path, bad);
    const std::string msg = error_of([&] { spectrack::load_float_grid(path, "density", -1, "test"); });
    EXPECT_TRUE(contains(msg, c.why) && contains(msg, "grid \"density\"") && contains(msg, path)) << msg;
    EXPECT_THROW(spectrack::inspect_volume(path), spectrack::Error);
  }
}

// A fixed-size metadata value whose stored size disagrees with its type: OpenVDB reads the type's
// size anyway, so the walk refuses it (fuzz_vdb: the next length then read as 2 GiB).
TEST(VolumePrescan, MetadataSizeDisagreeingWithItsTypeIsRefused) {
  TempDir d;
  const std::string src = d.file("meta.vdb");
  write_vdb(src, blob(), openvdb::io::COMPRESS_BLOSC);
  std::string bytes = read_bytes(src);
  const size_t at = bytes.find("file_bbox_min");
  ASSERT_NE(at, std::string::npos);
  const size_t size_field = at + std::string("file_bbox_min").size() + 4 + std::string("vec3i").size();
  const uint32_t zero = 0;
  std::memcpy(&bytes[size_field], &zero, 4);
  const std::string path = d.file("bad.vdb");
  write_bytes(path, bytes);
  const std::string msg = error_of([&] { spectrack::load_float_grid(path, "density", -1, "test"); });
  EXPECT_TRUE(contains(msg, "vec3i metadata value of 0 bytes")) << msg;
  EXPECT_THROW(spectrack::list_grids(path), spectrack::Error);
}

// DelayedLoadMetadata allocates each of its arrays by a size stored in the file before reading it
// (fuzz_vdb: 2 GB for a 21-byte value): a stored size beyond the value is refused, naming it,
// before OpenVDB reads the metadata; the file as written loads (the twin).
TEST(VolumePrescan, DelayedLoadArrayLargerThanItsValueIsRefused) {
  TempDir d;
  const std::string src = d.file("delayed.vdb");
  write_vdb(src, blob(), openvdb::io::COMPRESS_BLOSC);
  EXPECT_NO_THROW(spectrack::load_float_grid(src, "density", -1, "test"));
  std::string bytes = read_bytes(src);
  const size_t at = bytes.find("__delayedload");
  ASSERT_NE(at, std::string::npos) << "OpenVDB no longer writes delayed-load metadata";
  // the type, then the value's size, the leaf count and the masks' stored size (0: raw, one byte a leaf)
  size_t p = at + std::string("__delayedload").size();
  uint32_t size = 0, count = 0, masks = 0;
  std::memcpy(&size, &bytes[p], 4);
  std::memcpy(&count, &bytes[p + 4], 4);
  std::memcpy(&masks, &bytes[p + 8], 4);
  p += 12 + (masks == 0 ? count : masks);  // the sizes' stored size (0xffffffff: none stored)
  ASSERT_LE(p + 4, at + std::string("__delayedload").size() + 4 + size);
  const uint32_t huge = 0x82000000u;
  std::memcpy(&bytes[p], &huge, 4);
  const std::string path = d.file("bad.vdb");
  write_bytes(path, bytes);
  const std::string msg = error_of([&] { spectrack::list_grids(path); });
  EXPECT_TRUE(contains(msg, "delayed-load sizes") && contains(msg, "2181038080")) << msg;
  EXPECT_THROW(spectrack::load_float_grid(path, "density", -1, "test"), spectrack::Error);
}

// Every bit of the tree data, flipped one at a time, in blosc, zip, uncompressed and half-float
// files: each load either succeeds or ends in an Error (under ASan: no out-of-bounds access).
TEST(VolumePrescan, FlippedBitsLoadOrAreRefused) {
  TempDir d;
  struct Form { uint32_t compression; bool half; };
  using namespace openvdb::io;
  for (const Form& f : {Form{COMPRESS_BLOSC | COMPRESS_ACTIVE_MASK, false}, Form{COMPRESS_ZIP | COMPRESS_ACTIVE_MASK, false},
                        Form{COMPRESS_ACTIVE_MASK, false}, Form{COMPRESS_BLOSC | COMPRESS_ACTIVE_MASK, true}}) {
    auto g = blob();
    g->setSaveFloatAsHalf(f.half);
    const std::string src = d.file("src.vdb");
    write_vdb(src, g, f.compression);
    const std::string bytes = read_bytes(src);
    std::mt19937 rng(1234);
    int refused = 0;
    const std::string path = d.file("flip.vdb");
    for (int k = 0; k < 100; ++k) {
      std::string bad = bytes;
      const size_t bit = std::uniform_int_distribution<size_t>(0, bad.size() * 8 - 1)(rng);
      bad[bit / 8] = char(bad[bit / 8] ^ (1 << (bit % 8)));
      write_bytes(path, bad);
      refused += !loads_or_refuses(path);
    }
    EXPECT_GT(refused, 0);  // some flips land in sizes and masks
  }
}

// The flips of issue reports in a third-party blosc file (Arnold's grids.vdb): each byte around
// 68120 with each bit flipped.
TEST(VolumePrescan, FlippedBitsInSharedBloscFile) {
  const std::string src = std::string(SHARED_DATA_DIR) + "/arnold-usd/grids.vdb";
  if (!fs::exists(src)) GTEST_SKIP() << "shared test file absent: " << src;
  TempDir d;
  const std::string bytes = read_bytes(src);
  ASSERT_GT(bytes.size(), 68200u);
  const std::string path = d.file("grids.vdb");
  for (size_t byte = 68100; byte < 68140; ++byte)
    for (int bit = 0; bit < 8; ++bit) {
      std::string bad = bytes;
      bad[byte] = char(bad[byte] ^ (1 << bit));
      write_bytes(path, bad);
      try {
        spectrack::inspect_volume(path);
      } catch (const spectrack::Error& e) {
        EXPECT_TRUE(contains(e.what(), path)) << e.what();
      }
    }
}

// ---- inactive values read 0 -------------------------------------------------------------------

// Inactive voxels and tiles holding +inf, 1e30, negative values and deactivated densities load
// as the same grid as one whose inactive values are 0: same lookups, same majorants, from .vdb
// and from .nvdb.
TEST(VolumeInactive, InactiveValuesReadZero) {
  TempDir d;
  auto clean = blob();
  auto dirty = clean->deepCopy();
  auto acc = dirty->getAccessor();
  acc.setValueOff({21, 10, 10}, std::numeric_limits<float>::infinity());
  acc.setValueOff({10, 21, 10}, 1e30f);
  acc.setValueOff({10, 10, 21}, -5.0f);
  acc.setValueOff({1, 10, 10}, 7.0f);                                   // deactivated, value kept
  dirty->tree().addTile(1, openvdb::Coord(128, 0, 0), 1e30f, false);    // an inactive 128^3 tile
  dirty->tree().addTile(1, openvdb::Coord(-128, 0, 0), -3.0f, false);
  ASSERT_EQ(clean->activeVoxelCount(), dirty->activeVoxelCount());
  write_vdb(d.file("clean.vdb"), clean, openvdb::io::COMPRESS_BLOSC | openvdb::io::COMPRESS_ACTIVE_MASK);
  write_vdb(d.file("dirty.vdb"), dirty, openvdb::io::COMPRESS_ZIP);
  nanovdb::io::writeGrid(d.file("dirty.nvdb"), nanovdb::openToNanoVDB(*dirty), nanovdb::io::Codec::NONE);
  const GridData ref = spectrack::load_float_grid(d.file("clean.vdb"), "density", -1, "test");
  const MajorantGrid mref = spectrack::build_majorant_grid(ref, 4);
  for (const char* name : {"dirty.vdb", "dirty.nvdb"}) {
    const GridData g = spectrack::load_float_grid(d.file(name), "density", -1, "test");
    EXPECT_EQ(g.index_min, ref.index_min);
    EXPECT_EQ(g.index_max, ref.index_max);
    EXPECT_EQ(g.value_max, ref.value_max);
    for (double x = -1; x <= 23; x += 0.5)
      for (double y = -1; y <= 23; y += 0.75)
        for (double z : {0.5, 10.0, 10.25, 20.5, 21.0})
          ASSERT_EQ(spectrack::sample_index_trilinear(g, x, y, z), spectrack::sample_index_trilinear(ref, x, y, z))
              << name << " at " << x << ", " << y << ", " << z;
    EXPECT_EQ(spectrack::sample_index_trilinear(g, 150, 10, 10), 0.0f) << name;
    EXPECT_EQ(spectrack::sample_index_trilinear(g, -100, 10, 10), 0.0f) << name;
    const MajorantGrid m = spectrack::build_majorant_grid(g, 4);
    EXPECT_EQ(m.dmax, mref.dmax) << name;
    EXPECT_EQ(m.dmin, mref.dmin) << name;
  }
}

// ---- sparse majorant build --------------------------------------------------------------------

// Three active voxels spread over 60000 voxels: the majorant grid and hierarchy are built in
// time bounded by the voxels, not by the 60000^3 box (it took about an hour visiting every block).
TEST(VolumeMajorant, FarApartVoxelsBuildQuickly) {
  TempDir d;
  auto g = blob();
  g->clear();
  auto acc = g->getAccessor();
  acc.setValue({0, 0, 0}, 1.0f);
  acc.setValue({60000, 10, 0}, 2.0f);
  acc.setValue({30000, 60000, 60000}, 3.0f);
  write_vdb(d.file("far.vdb"), g, openvdb::io::COMPRESS_BLOSC | openvdb::io::COMPRESS_ACTIVE_MASK);
  const GridData grid = spectrack::load_float_grid(d.file("far.vdb"), "density", -1, "test");
  const auto t0 = std::chrono::steady_clock::now();
  const int cell = spectrack::auto_majorant_cell(grid);
  const MajorantGrid m = spectrack::build_majorant_grid(grid, cell);
  const spectrack::MajorantHierarchy h = spectrack::build_majorant_hierarchy(m, 8, spectrack::MajorantCostModel{});
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_LT(seconds, 3.0) << "cell " << cell << ", " << m.dmax.size() << " cells";
  EXPECT_GE(h.blocks_empty, 1u);
  // each voxel lies inside a cell bounded by its value; all but a few cells are empty
  size_t nonempty = 0;
  for (float v : m.dmax) nonempty += v > 0.0f;
  EXPECT_GE(nonempty, 3u);
  EXPECT_LE(nonempty, 3u * 8u);
  for (const auto& [p, v] : {std::pair<std::array<int, 3>, float>{{0, 0, 0}, 1.0f}, {{60000, 10, 0}, 2.0f},
                             {{30000, 60000, 60000}, 3.0f}}) {
    size_t idx = 0, stride = 1;
    for (int a = 0; a < 3; ++a) {
      idx += size_t((p[a] - m.origin[a]) / m.cell) * stride;
      stride *= size_t(m.dims[a]);
    }
    EXPECT_GE(m.dmax[idx], v);
  }
}

// The sparse build gives exactly the bounds of the dense walk over every cell's support.
TEST(VolumeMajorant, SparseBuildMatchesDenseWalk) {
  TempDir d;
  auto g = blob();
  auto acc = g->getAccessor();
  acc.setValue({200, 40, -30}, 0.5f);                                  // a stray voxel
  g->tree().addTile(1, openvdb::Coord(256, 0, 0), 0.25f, true);         // an active 128^3 tile
  write_vdb(d.file("mixed.vdb"), g, openvdb::io::COMPRESS_BLOSC | openvdb::io::COMPRESS_ACTIVE_MASK);
  const GridData grid = spectrack::load_float_grid(d.file("mixed.vdb"), "density", -1, "test");
  for (int cell : {3, 8, 16}) {
    const MajorantGrid m = spectrack::build_majorant_grid(grid, cell);
    for (size_t idx = 0; idx < m.dmax.size(); idx += 7) {
      const int c[3] = {int(idx % size_t(m.dims[0])), int(idx / size_t(m.dims[0]) % size_t(m.dims[1])),
                        int(idx / (size_t(m.dims[0]) * size_t(m.dims[1])))};
      float hi = -std::numeric_limits<float>::infinity(), lo = -hi;
      for (int z = 0; z <= cell; ++z)
        for (int y = 0; y <= cell; ++y)
          for (int x = 0; x <= cell; ++x) {
            const float v = spectrack::sample_index_trilinear(grid, m.origin[0] + c[0] * cell + x, m.origin[1] + c[1] * cell + y,
                                                              m.origin[2] + c[2] * cell + z);
            hi = std::max(hi, v);
            lo = std::min(lo, v);
          }
      hi = hi * (1.0f + 1e-5f);
      if (hi > 0.0f) hi += 1e-30f;
      ASSERT_EQ(m.dmax[idx], hi) << "cell size " << cell << ", cell " << idx;
      ASSERT_EQ(m.dmin[idx], lo * (1.0f - 1e-5f)) << "cell size " << cell << ", cell " << idx;
    }
  }
}

// ---- info ---------------------------------------------------------------------------------------

TEST(VolumeInfo, ControlCharactersInNamesAreEscaped) {
  EXPECT_EQ(spectrack::printable_name("a\x1b[2Jb\n\"\\"), "a\\x1b[2Jb\\x0a\\\"\\\\");
  TempDir d;
  write_vdb(d.file("names.vdb"), blob("den\x1bsity"), openvdb::io::COMPRESS_BLOSC);
  const std::string msg = error_of([&] { spectrack::load_float_grid(d.file("names.vdb"), "nothing", -1, "test"); });
  EXPECT_TRUE(contains(msg, "den\\x1bsity") && !contains(msg, "\x1b")) << msg;
}

// A .nvdb grid whose checksum does not match: refused by info as by the loader.
TEST(VolumeInfo, NanoVdbChecksumRefusedByInfoAsByRender) {
  TempDir d;
  auto h = nanovdb::openToNanoVDB(*blob(), nanovdb::StatsMode::Default, nanovdb::ChecksumMode::Full);
  const std::string good = d.file("good.nvdb"), bad = d.file("bad.nvdb");
  nanovdb::io::writeGrid(good, h, nanovdb::io::Codec::NONE);
  EXPECT_NO_THROW(spectrack::inspect_volume(good));
  // one voxel value changed after the checksum was computed
  auto* leaf = h.grid<float>()->tree().getFirstNode<0>();
  ASSERT_NE(leaf, nullptr);
  const_cast<nanovdb::NanoLeaf<float>*>(leaf)->setValueOnly(0, 123.0f);
  nanovdb::io::writeGrid(bad, h, nanovdb::io::Codec::NONE);
  const std::string render_msg = error_of([&] { spectrack::load_float_grid(bad, "density", -1, "test"); });
  const std::string info_msg = error_of([&] { spectrack::inspect_volume(bad); });
  EXPECT_TRUE(contains(render_msg, "checksum")) << render_msg;
  EXPECT_TRUE(contains(info_msg, "checksum") && contains(info_msg, bad)) << info_msg;
}

// A NanoVDB lookup finds a voxel through the tree's slots, while the active box, the value range
// and the majorant grid's occupancy read the nodes' stored origins: a leaf whose origin disagrees
// with its slot (a flipped byte that a partial or absent checksum does not cover) rendered voxels
// where every bound read 0 (fuzz_nvdb: a majorant of 0 under a density of 1.05). Such a file is
// refused naming the two coordinates; the same grid unmodified loads (the twin).
TEST(VolumeInfo, NanoVdbNodeWhoseOriginIsNotItsPlaceIsRefused) {
  TempDir d;
  auto h = nanovdb::openToNanoVDB(*blob(), nanovdb::StatsMode::Default, nanovdb::ChecksumMode::Disable);
  const std::string good = d.file("good.nvdb"), bad = d.file("bad.nvdb");
  nanovdb::io::writeGrid(good, h, nanovdb::io::Codec::NONE);
  EXPECT_NO_THROW(spectrack::load_float_grid(good, "density", -1, "test"));
  auto* leaf = const_cast<nanovdb::NanoLeaf<float>*>(h.grid<float>()->tree().getFirstNode<0>());
  ASSERT_NE(leaf, nullptr);
  leaf->data()->mBBoxMin += nanovdb::Coord(4096, 0, 0);  // the leaf claims to lie 4096 voxels away
  nanovdb::io::writeGrid(bad, h, nanovdb::io::Codec::NONE);
  const std::string render_msg = error_of([&] { spectrack::load_float_grid(bad, "density", -1, "test"); });
  const std::string info_msg = error_of([&] { spectrack::inspect_volume(bad); });
  EXPECT_TRUE(contains(render_msg, "corrupt NanoVDB grid") && contains(render_msg, "sits at")) << render_msg;
  EXPECT_TRUE(contains(info_msg, "sits at") && contains(info_msg, bad)) << info_msg;
}
