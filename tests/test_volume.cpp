// test_volume.cpp: tests for src/volume (VDB loading, majorant grid, host trilinear lookups).
//
// Real data comes from SHARED_DATA_DIR (third-party VDBs, see its README); a test whose file is
// absent is skipped. Synthetic grids are written to temporary .vdb/.nvdb files so that they go
// through the same loader as user files. The majorant tests sample the trilinear field at many
// random points and check dmin <= density <= dmax per cell; the synthetic grid puts a one-voxel
// sheet on a cell boundary, where a support without the interpolation apron is too small, and
// the test checks that such a narrowed bound would indeed be caught.
#include <gtest/gtest.h>

#include <unistd.h>

#include <chrono>
#include <cstring>
#include <cmath>
#include <filesystem>
#include <functional>
#include <limits>
#include <algorithm>
#include <fstream>
#include <random>
#include <sstream>

#include <openvdb/io/Compression.h>
#include <openvdb/openvdb.h>
#include <openvdb/tools/Interpolation.h>

#include <nanovdb/util/IO.h>
#include <nanovdb/util/OpenToNanoVDB.h>

#include "scene/scene_pack.h"
#include "volume/inspect.h"
#include "volume/velocity_grid.h"
#include "volume/volume.h"
#include "test_util.h"

namespace fs = std::filesystem;
using spectrack::GridData;
using spectrack::MajorantGrid;

using st_test::error_of;

namespace {

std::string data_path(const std::string& rel) { return std::string(SHARED_DATA_DIR) + "/" + rel; }

#define REQUIRE_FILE(path)                                                   \
  do {                                                                       \
    if (!fs::exists(path)) GTEST_SKIP() << "shared test file absent: " << (path); \
  } while (0)

// A temporary file removed when the test ends.
struct TempFile {
  std::string path;
  explicit TempFile(const std::string& name) {
    const fs::path dir = fs::temp_directory_path() / ("spectrack_test_volume_" + std::to_string(::getpid()));
    fs::create_directories(dir);
    path = (dir / name).string();
  }
  ~TempFile() {
    std::error_code ec;
    fs::remove(path, ec);
    fs::remove(fs::path(path).parent_path(), ec);  // only succeeds once the folder is empty
  }
};

openvdb::FloatGrid::Ptr new_grid(const std::string& name = "density", float background = 0.0f) {
  openvdb::initialize();
  auto g = openvdb::FloatGrid::create(background);
  g->setName(name);
  g->setGridClass(openvdb::GRID_FOG_VOLUME);
  return g;
}

void write_vdb(const std::string& path, const openvdb::GridPtrVec& grids) {
  openvdb::io::File f(path);
  f.write(grids);
  f.close();
}

openvdb::FloatGrid::Ptr read_vdb(const std::string& path, const std::string& name) {
  openvdb::initialize();
  openvdb::io::File f(path);
  f.open(false);
  auto g = openvdb::gridPtrCast<openvdb::FloatGrid>(f.readGrid(name));
  f.close();
  return g;
}

bool contains(const std::string& s, const std::string& sub) { return s.find(sub) != std::string::npos; }

std::array<double, 3> apply(const double m[3][4], double x, double y, double z) {
  std::array<double, 3> w;
  for (int r = 0; r < 3; ++r) w[r] = m[r][0] * x + m[r][1] * y + m[r][2] * z + m[r][3];
  return w;
}

// index_to_world must reproduce OpenVDB's own indexToWorld.
void expect_same_map(const GridData& g, const openvdb::math::Transform& xf) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-100, 100);
  for (int i = 0; i < 20; ++i) {
    const double x = u(rng), y = u(rng), z = u(rng);
    const auto w = apply(g.index_to_world, x, y, z);
    const openvdb::Vec3d ref = xf.indexToWorld(openvdb::Vec3d(x, y, z));
    for (int a = 0; a < 3; ++a) EXPECT_NEAR(w[a], ref[a], 1e-9 * (1 + std::abs(ref[a])));
  }
}

int cell_index(const MajorantGrid& m, const std::array<int, 3>& c) {
  return c[0] + m.dims[0] * (c[1] + m.dims[1] * c[2]);
}

// Samples the trilinear field at n points in the majorant box (half uniform, half near the
// active voxels listed in `hot`) and checks the per-cell bounds. Returns how many samples
// exceed a bound built without the interpolation apron (voxels c*B .. c*B+B-1 only).
int check_majorant(const GridData& g, const openvdb::FloatGrid& ref, int cell, int n,
                   const std::vector<openvdb::Coord>& hot) {
  const MajorantGrid m = spectrack::build_majorant_grid(g, cell);
  EXPECT_EQ(m.cell, cell);
  for (int a = 0; a < 3; ++a) {
    EXPECT_EQ(m.origin[a], g.index_min[a] - 1);
    EXPECT_EQ(m.dims[a], (g.index_max[a] - g.index_min[a] + 2 + cell - 1) / cell);
  }
  EXPECT_EQ(m.dmax.size(), size_t(m.dims[0]) * m.dims[1] * m.dims[2]);
  EXPECT_EQ(m.dmin.size(), m.dmax.size());
  std::mt19937 rng(12345 + cell);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  std::vector<float> narrow(m.dmax.size(), -1.0f);
  auto acc = ref.getConstAccessor();
  int failures = 0, narrow_violations = 0;
  for (int i = 0; i < n; ++i) {
    double p[3];
    if (i % 2 == 0 || hot.empty()) {
      for (int a = 0; a < 3; ++a) p[a] = m.origin[a] + u01(rng) * (double(m.dims[a]) * cell);
    } else {
      const openvdb::Coord& c = hot[size_t(u01(rng) * hot.size()) % hot.size()];
      for (int a = 0; a < 3; ++a) p[a] = c[a] + (2.0 * u01(rng) - 1.0);
    }
    std::array<int, 3> ci;
    bool inside = true;
    for (int a = 0; a < 3; ++a) {
      ci[a] = int(std::floor((p[a] - m.origin[a]) / cell));
      inside = inside && ci[a] >= 0 && ci[a] < m.dims[a];
    }
    if (!inside) continue;
    const int k = cell_index(m, ci);
    const float v = spectrack::sample_index_trilinear(g, p[0], p[1], p[2]);
    if (!(m.dmin[size_t(k)] <= v && v <= m.dmax[size_t(k)])) {
      if (++failures <= 5) {
        ADD_FAILURE() << "cell " << cell << ": density " << v << " at (" << p[0] << ", " << p[1] << ", " << p[2]
                      << ") outside [" << m.dmin[size_t(k)] << ", " << m.dmax[size_t(k)] << "]";
      }
    }
    if (narrow[size_t(k)] < 0) {
      float hi = 0;
      for (int z = 0; z < cell; ++z)
        for (int y = 0; y < cell; ++y)
          for (int x = 0; x < cell; ++x)
            hi = std::max(hi, acc.getValue(openvdb::Coord(m.origin[0] + ci[0] * cell + x,
                                                          m.origin[1] + ci[1] * cell + y,
                                                          m.origin[2] + ci[2] * cell + z)));
      narrow[size_t(k)] = hi * (1.0f + 1e-5f);
    }
    narrow_violations += v > narrow[size_t(k)];
  }
  EXPECT_EQ(failures, 0) << "cell size " << cell;
  return narrow_violations;
}

// A fog grid with random values on a spherical shell, a one-voxel sheet on a plane that is a
// cell boundary for cells 4, 8 and 16, an isolated voxel and an active 8^3 tile; `hot` gets
// the voxels near which samples concentrate.
openvdb::FloatGrid::Ptr shell_and_sheet(std::vector<openvdb::Coord>* hot) {
  auto g = new_grid();
  auto acc = g->getAccessor();
  std::mt19937 rng(99);
  std::uniform_real_distribution<float> val(0.05f, 1.0f);
  for (int z = -22; z <= 22; ++z)
    for (int y = -22; y <= 22; ++y)
      for (int x = -22; x <= 22; ++x) {
        const double r = std::sqrt(double(x * x + y * y + z * z));
        if (std::abs(r - 20.0) < 0.8) acc.setValue(openvdb::Coord(x, y, z), val(rng));
      }
  const openvdb::CoordBBox box = g->evalActiveVoxelBoundingBox();
  const int xs = box.min().x() - 1 + 32;
  for (int z = -6; z <= 6; ++z)
    for (int y = -6; y <= 6; ++y) {
      acc.setValue(openvdb::Coord(xs, y, z), 4.0f + val(rng));
      hot->push_back(openvdb::Coord(xs, y, z));
    }
  acc.setValue(openvdb::Coord(3, -7, 5), 2.5f);
  hot->push_back(openvdb::Coord(3, -7, 5));
  g->tree().addTile(1, openvdb::Coord(8, 0, 0), 0.7f, true);
  hot->push_back(openvdb::Coord(8, 0, 0));
  hot->push_back(openvdb::Coord(15, 7, 7));
  return g;
}

}  // namespace

// ---- loading real data ------------------------------------------------------------------------

TEST(VolumeLoad, DisneyCloud) {
  const std::string path = data_path("wdas_cloud_sixteenth.vdb");
  REQUIRE_FILE(path);
  const GridData g = spectrack::load_float_grid(path, "density", -1, "test");
  EXPECT_EQ(g.name, "density");
  EXPECT_FALSE(g.empty);
  EXPECT_EQ(g.index_min, (std::array<int, 3>{-66, -21, -90}));
  EXPECT_EQ(g.index_max, (std::array<int, 3>{59, 64, 63}));
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) EXPECT_NEAR(g.index_to_world[r][c], r == c ? 3.33 : 0.0, 0.01);
  EXPECT_GE(g.value_min, 0.0f);
  EXPECT_LE(g.value_max, 1.0f);
  EXPECT_GT(g.value_max, 0.5f);
  ASSERT_NE(g.handle.grid<float>(), nullptr);
  expect_same_map(g, read_vdb(path, "density")->transform());
}

TEST(VolumeLoad, NonUniformVoxelSizeAndTranslation) {
  const std::string path = data_path("usd/densityAndHeat.vdb");
  REQUIRE_FILE(path);
  const GridData g = spectrack::load_float_grid(path, "density", -1, "test");
  expect_same_map(g, read_vdb(path, "density")->transform());
  EXPECT_NEAR(g.index_to_world[0][0], 0.703, 0.001);
  EXPECT_NEAR(g.index_to_world[2][2], 0.716, 0.001);
  EXPECT_NE(g.index_to_world[0][3], 0.0);
  const GridData heat = spectrack::load_float_grid(path, "heat", -1, "test");
  EXPECT_EQ(heat.name, "heat");
}

TEST(VolumeLoad, ListGrids) {
  const std::string path = data_path("usd/smoke_000001.vdb");
  REQUIRE_FILE(path);
  const std::vector<std::string> l = spectrack::list_grids(path);
  ASSERT_EQ(l.size(), 4u);
  std::string all;
  for (const auto& s : l) all += s + ";";
  EXPECT_TRUE(contains(all, "obstacles (int32")) << all;
  EXPECT_TRUE(contains(all, "velocity (vec3s")) << all;
  EXPECT_TRUE(contains(all, "density (float")) << all;
}

TEST(VolumeLoad, EmptyGridAndNonFloatGrids) {
  const std::string path = data_path("usd/smoke_000001.vdb");
  REQUIRE_FILE(path);
  const GridData g = spectrack::load_float_grid(path, "density", -1, "test");
  EXPECT_TRUE(g.empty);
  const MajorantGrid m = spectrack::build_majorant_grid(g, 8);
  EXPECT_EQ(m.dims, (std::array<int, 3>{1, 1, 1}));
  ASSERT_EQ(m.dmax.size(), 1u);
  EXPECT_EQ(m.dmax[0], 0.0f);
  EXPECT_EQ(m.dmin[0], 0.0f);
  EXPECT_EQ(spectrack::sample_index_trilinear(g, 0.5, 0.5, 0.5), 0.0f);

  std::string msg = error_of([&] { spectrack::load_float_grid(path, "obstacles", -1, "scene.json: /media/0"); });
  EXPECT_TRUE(contains(msg, "int32")) << msg;
  EXPECT_EQ(msg.rfind("scene.json: /media/0: " + path + ": ", 0), 0u) << msg;
  msg = error_of([&] { spectrack::load_float_grid(path, "velocity", -1, "test"); });
  EXPECT_TRUE(contains(msg, "vec3s")) << msg;
}

TEST(VolumeLoad, DuplicateGridNames) {
  const std::string path = data_path("arnold-usd/grids.vdb");
  REQUIRE_FILE(path);
  testing::internal::CaptureStderr();
  const GridData first = spectrack::load_float_grid(path, "density", -1, "test");
  const std::string warning = testing::internal::GetCapturedStderr();
  EXPECT_TRUE(contains(warning, "3 grids")) << warning;
  EXPECT_TRUE(contains(warning, "grid_index")) << warning;

  const GridData g0 = spectrack::load_float_grid(path, "density", 0, "test");
  const GridData g1 = spectrack::load_float_grid(path, "density", 1, "test");
  const GridData g2 = spectrack::load_float_grid(path, "density", 2, "test");
  EXPECT_EQ(first.index_min, g0.index_min);
  EXPECT_EQ(first.index_to_world[0][3], g0.index_to_world[0][3]);
  // The middle grid has its own bbox; the first and third differ in their transforms.
  EXPECT_EQ(g1.index_min, (std::array<int, 3>{-9, -13, -9}));
  EXPECT_EQ(g1.index_max, (std::array<int, 3>{9, 5, 12}));
  EXPECT_EQ(g2.index_min, (std::array<int, 3>{-5, -5, -5}));
  bool differ = false;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) differ = differ || g0.index_to_world[r][c] != g2.index_to_world[r][c];
  EXPECT_TRUE(differ);
  const std::string msg = error_of([&] { spectrack::load_float_grid(path, "density", 3, "test"); });
  EXPECT_TRUE(contains(msg, "out of range")) << msg;
}

// A double grid (Houdini's 64-bit volumes) is read as float: the same grid as its float copy, and a
// value no float holds is refused by name rather than read as infinity.
TEST(VolumeLoad, DoubleGridIsReadAsFloat) {
  using namespace st_test;
  const std::string dir = temp_dir("double_grid");
  auto value = [](int i, int j, int k) { return 0.1 + 0.01 * ((i * 7 + j * 3 + k) % 50); };
  auto write = [&](const std::string& path, bool as_double, double big) {
    openvdb::initialize();
    openvdb::GridBase::Ptr out;
    auto fill = [&](auto grid) {
      grid->setName("density");
      grid->setGridClass(openvdb::GRID_FOG_VOLUME);
      grid->setTransform(openvdb::math::Transform::createLinearTransform(0.25));
      auto acc = grid->getAccessor();
      for (int k = -5; k < 9; ++k)
        for (int j = 0; j < 6; ++j)
          for (int i = 3; i < 20; ++i) acc.setValue(openvdb::Coord(i, j, k), value(i, j, k));
      grid->tree().addTile(1, openvdb::Coord(32, 0, 0), 0.5, true);
      if (big != 0) acc.setValue(openvdb::Coord(4, 2, 1), big);
      out = grid;
    };
    if (as_double) fill(openvdb::DoubleGrid::create(0.0));
    else fill(openvdb::FloatGrid::create(0.0f));
    openvdb::io::File f(path);
    f.write({out});
    f.close();
  };
  write(dir + "/f.vdb", false, 0);
  write(dir + "/d.vdb", true, 0);
  const GridData f = spectrack::load_float_grid(dir + "/f.vdb", "density", -1, "test");
  const GridData d = spectrack::load_float_grid(dir + "/d.vdb", "density", -1, "test");
  EXPECT_EQ(d.index_min, f.index_min);
  EXPECT_EQ(d.index_max, f.index_max);
  EXPECT_EQ(d.value_min, f.value_min);
  EXPECT_EQ(d.value_max, f.value_max);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) EXPECT_EQ(d.index_to_world[r][c], f.index_to_world[r][c]);
  for (double x : {3.5, 7.25, 12.0, 19.5, 36.0})
    EXPECT_EQ(spectrack::sample_index_trilinear(d, x, 2.5, 1.5), spectrack::sample_index_trilinear(f, x, 2.5, 1.5)) << x;
  EXPECT_EQ(spectrack::sample_index_trilinear(d, 36.0, 2.5, 1.5), 0.5f);  // the active tile
  const std::vector<spectrack::GridInfo> info = spectrack::inspect_volume(dir + "/d.vdb");  // `info`
  ASSERT_EQ(info.size(), 1u);
  EXPECT_EQ(info[0].density_use, "yes (64-bit values, read as 32-bit floats)");
  EXPECT_EQ(info[0].nanovdb_bytes, spectrack::inspect_volume(dir + "/f.vdb")[0].nanovdb_bytes);
  write(dir + "/big.vdb", true, 1e300);
  std::string msg = error_of([&] { spectrack::load_float_grid(dir + "/big.vdb", "density", -1, "test"); });
  EXPECT_TRUE(contains(msg, "value 1e+300 at active voxel (4, 2, 1) is beyond a 32-bit float's range")) << msg;
  EXPECT_EQ(spectrack::inspect_volume(dir + "/big.vdb")[0].density_use, "no: values beyond a 32-bit float's range");
  write(dir + "/neg.vdb", true, -2);
  msg = error_of([&] { spectrack::load_float_grid(dir + "/neg.vdb", "density", -1, "test"); });
  EXPECT_TRUE(contains(msg, "-2 at active voxel (4, 2, 1) is negative")) << msg;
}

// vec3d colour and velocity grids (Houdini's 64-bit vectors) read as their vec3s copies.
TEST(VolumeLoad, Vec3dColourAndVelocityGridsReadAsFloat) {
  using namespace st_test;
  const std::string dir = temp_dir("vec3d_grids");
  auto write = [&](const std::string& path, bool as_double) {
    openvdb::initialize();
    auto density = openvdb::FloatGrid::create(0.0f);
    density->setName("density");
    density->setGridClass(openvdb::GRID_FOG_VOLUME);
    openvdb::GridPtrVec grids{density};
    auto vec = [&](auto grid, const char* name, double scale) {
      grid->setName(name);
      grid->setGridClass(std::string(name) == "vel" ? openvdb::GRID_STAGGERED : openvdb::GRID_UNKNOWN);
      auto acc = grid->getAccessor();
      using Value = typename std::decay_t<decltype(*grid)>::ValueType;  // Vec3f or Vec3d
      for (int i = 0; i < 6; ++i) acc.setValue(openvdb::Coord(i, 1, 2), Value(scale * 0.1 * i, scale * 0.5, scale * 0.3));
      grids.push_back(grid);
    };
    for (int i = 0; i < 6; ++i) density->tree().setValue(openvdb::Coord(i, 1, 2), 0.5f);
    if (as_double) {
      vec(openvdb::Vec3DGrid::create(openvdb::Vec3d(0.0)), "Cd", 1.0);
      vec(openvdb::Vec3DGrid::create(openvdb::Vec3d(0.0)), "vel", 3.0);
    } else {
      vec(openvdb::Vec3SGrid::create(openvdb::Vec3s(0.0f)), "Cd", 1.0);
      vec(openvdb::Vec3SGrid::create(openvdb::Vec3s(0.0f)), "vel", 3.0);
    }
    openvdb::io::File f(path);
    f.write(grids);
    f.close();
  };
  write(dir + "/s.vdb", false);
  write(dir + "/d.vdb", true);
  const auto cs = spectrack::load_color_grid(dir + "/s.vdb", "Cd", "test");
  const auto cd = spectrack::load_color_grid(dir + "/d.vdb", "Cd", "test");
  for (int c = 0; c < 3; ++c) {
    EXPECT_EQ(cd[c].index_min, cs[c].index_min);
    EXPECT_EQ(cd[c].value_max, cs[c].value_max);
    EXPECT_EQ(spectrack::sample_index_trilinear(cd[c], 3.5, 1.0, 2.0), spectrack::sample_index_trilinear(cs[c], 3.5, 1.0, 2.0));
  }
  const spectrack::VelocityGrid vs = spectrack::load_velocity_grid(dir + "/s.vdb", "vel", 1e9, "test");
  const spectrack::VelocityGrid vd = spectrack::load_velocity_grid(dir + "/d.vdb", "vel", 1e9, "test");
  EXPECT_TRUE(vd.staggered);
  EXPECT_EQ(vd.max_abs, vs.max_abs);
  EXPECT_EQ(vd.max_speed, vs.max_speed);
  EXPECT_EQ(vd.grid.handle.size(), vs.grid.handle.size());
  const std::vector<spectrack::GridInfo> info = spectrack::inspect_volume(dir + "/d.vdb");
  ASSERT_EQ(info.size(), 3u);
  for (const spectrack::GridInfo& g : info) {
    if (g.name == "Cd") EXPECT_TRUE(contains(g.density_use, "usable as a medium's colour grid")) << g.density_use;
    if (g.name == "vel") EXPECT_TRUE(contains(g.velocity_use, "yes (staggered)")) << g.velocity_use;
  }
  // a density grid is not a colour grid, whatever its precision
  EXPECT_TRUE(contains(error_of([&] { spectrack::load_color_grid(dir + "/d.vdb", "density", "test"); }),
                       "must be a vec3s (or vec3d) grid"));
}

// `info` reports a grid, then packs the scene as render does: the pack takes the kept grid instead
// of reading the file again (the file is removed in between: a second read would fail).
TEST(VolumeLoad, KeptGridIsHandedOverOnceWithoutReadingTheFileAgain) {
  using namespace st_test;
  const std::string dir = temp_dir("kept_grids");
  const std::string path = dir + "/lumpy.vdb";
  write_lumpy(path);
  const GridData fresh = spectrack::load_float_grid(path, "density", -1, "test");
  {
    spectrack::KeptGrids kept;
    const GridData& g = kept.load(path, "density", -1, "test");
    EXPECT_EQ(&g, &kept.load(path, "density", -1, "test"));  // kept: not loaded twice
    EXPECT_THROW(spectrack::KeptGrids(), std::logic_error);  // one at a time
    std::filesystem::remove(path);
    const GridData taken = spectrack::load_float_grid(path, "density", -1, "test");
    EXPECT_EQ(taken.index_min, fresh.index_min);
    EXPECT_EQ(taken.index_max, fresh.index_max);
    EXPECT_EQ(taken.value_max, fresh.value_max);
    EXPECT_EQ(taken.handle.size(), fresh.handle.size());
    // handed over once; a load that fails keeps nothing
    EXPECT_TRUE(contains(error_of([&] { spectrack::load_float_grid(path, "density", -1, "test"); }), path));
    EXPECT_THROW(kept.load(path, "density", -1, "test"), spectrack::Error);
  }
  // the scene's pack takes it: a scene packed while the file is gone
  write_lumpy(path);
  const nlohmann::json j = {
      {"format", "spectrack-scene/1"},
      {"camera", {{"type", "perspective"}, {"position", {0, 0, -4}}, {"look_at", {0, 0, 0}}, {"up", {0, 1, 0}}, {"fov_deg", 40}}},
      {"film", {{"width", 8}, {"height", 8}, {"spp", 1}}},
      {"lights", {{{"type", "environment"}, {"radiance", {1, 1, 1}}}}},
      {"media", {{{"type", "vdb"}, {"file", "lumpy.vdb"}, {"sigma_s", {1, 1, 1}}, {"sigma_a", {0, 0, 0}}}}}};
  const spectrack::SceneDesc scene = scene_from_json(j, dir);
  const spectrack::RenderSettings set = spectrack::resolve_settings(scene, quiet_options());
  {
    spectrack::KeptGrids kept;
    kept.load(scene.media[0].file, scene.media[0].grid, scene.media[0].grid_index, "test");
    std::filesystem::remove(path);
    EXPECT_NO_THROW(spectrack::pack_scene(scene, set, spectrack::pack_options(set)));
    EXPECT_THROW(spectrack::pack_scene(scene, set, spectrack::pack_options(set)), spectrack::Error);
  }
}

// ---- errors -----------------------------------------------------------------------------------

TEST(VolumeErrors, DamagedFiles) {
  const std::string dir = data_path("oiio/openvdb-damaged");
  REQUIRE_FILE(dir);
  int n = 0;
  for (const auto& entry : fs::directory_iterator(dir)) {
    const std::string path = entry.path().string();
    ++n;
    const std::string msg = error_of([&] { spectrack::load_float_grid(path, "density", -1, "test"); });
    EXPECT_TRUE(contains(msg, path)) << msg;
    // Loading each file's own grid gives an Error too, except the well-formed empty one.
    const std::string stem = entry.path().stem().string();
    const std::string own = stem.rfind("bad-bbox-", 0) == 0 ? stem.substr(9) : stem;
    if (entry.path().stem() == "bad-bbox-empty") {
      EXPECT_TRUE(spectrack::load_float_grid(path, "empty", -1, "test").empty);
    } else if (entry.path().stem() != "truncated") {
      const std::string m2 = error_of([&] { spectrack::load_float_grid(path, own, -1, "test"); });
      EXPECT_TRUE(contains(m2, "file_bbox")) << m2;
    }
  }
  EXPECT_EQ(n, 7);
}

TEST(VolumeErrors, LevelSets) {
  for (const char* f : {"levelset/cube.vdb", "levelset/sphere.vdb"}) {
    const std::string path = data_path(f);
    REQUIRE_FILE(path);
    const std::string name = contains(f, "cube") ? "ls_cube" : "ls_sphere";
    const std::string msg = error_of([&] { spectrack::load_float_grid(path, name, -1, "test"); });
    EXPECT_TRUE(contains(msg, "level set")) << msg;
  }
}

TEST(VolumeErrors, MissingGridListsGrids) {
  const std::string path = data_path("usd/densityAndHeat.vdb");
  REQUIRE_FILE(path);
  const std::string msg = error_of([&] { spectrack::load_float_grid(path, "smoke", -1, "test"); });
  EXPECT_TRUE(contains(msg, "\"smoke\"")) << msg;
  EXPECT_TRUE(contains(msg, "density (float")) << msg;
  EXPECT_TRUE(contains(msg, "heat (float")) << msg;
}

TEST(VolumeErrors, MissingAndBadFiles) {
  std::string msg = error_of([] { spectrack::load_float_grid("/nonexistent/cloud.vdb", "density", -1, "ctx"); });
  EXPECT_TRUE(contains(msg, "ctx: /nonexistent/cloud.vdb: no such file")) << msg;
  msg = error_of([] { spectrack::load_float_grid("/nonexistent/cloud.nvdb", "density", -1, "ctx"); });
  EXPECT_TRUE(contains(msg, "no such file")) << msg;
  msg = error_of([] { spectrack::load_float_grid("cloud.txt", "density", -1, "ctx"); });
  EXPECT_TRUE(contains(msg, "extension")) << msg;
  for (const char* name : {"garbage.vdb", "garbage.nvdb"}) {
    TempFile t(name);
    std::ofstream(t.path, std::ios::binary) << std::string(1000, 'x');
    msg = error_of([&] { spectrack::load_float_grid(t.path, "density", -1, "ctx"); });
    EXPECT_TRUE(contains(msg, t.path)) << msg;
  }
  EXPECT_THROW(spectrack::list_grids("/nonexistent/cloud.vdb"), spectrack::Error);
}

TEST(VolumeErrors, BadValuesBackgroundAndTransform) {
  struct Case {
    const char* what;
    std::function<openvdb::FloatGrid::Ptr()> make;
    std::vector<std::string> expect;
  };
  const std::vector<Case> cases = {
      {"negative voxel", [] { auto g = new_grid(); g->tree().setValue({1, 1, 1}, 0.5f); g->tree().setValue({3, 4, 5}, -0.5f); return g; },
       {"-0.5", "(3, 4, 5)", "negative"}},
      {"NaN voxel", [] { auto g = new_grid(); g->tree().setValue({-7, 2, 9}, std::nanf("")); return g; },
       {"nan", "(-7, 2, 9)"}},
      {"infinite voxel", [] { auto g = new_grid(); g->tree().setValue({0, 0, 0}, INFINITY); return g; },
       {"inf", "not finite"}},
      {"negative tile", [] { auto g = new_grid(); g->tree().addTile(1, openvdb::Coord(16, 0, 0), -2.0f, true); return g; },
       {"-2", "tile", "(16, 0, 0)"}},
      {"background", [] { auto g = new_grid("density", 0.25f); g->tree().setValue({0, 0, 0}, 1.0f); return g; },
       {"background", "0.25"}},
      {"frustum", [] {
         auto g = new_grid();
         g->tree().setValue({0, 0, 0}, 1.0f);
         g->setTransform(openvdb::math::Transform::createFrustumTransform(
             openvdb::BBoxd(openvdb::Vec3d(0), openvdb::Vec3d(10)), 0.5, 2.0, 1.0));
         return g;
       },
       {"non-affine"}},
  };
  for (const Case& c : cases) {
    TempFile t("bad.vdb");
    write_vdb(t.path, {c.make()});
    const std::string msg = error_of([&] { spectrack::load_float_grid(t.path, "density", -1, "test"); });
    for (const std::string& e : c.expect) EXPECT_TRUE(contains(msg, e)) << c.what << ": " << msg;
  }
}

TEST(VolumeErrors, HugeLengthPrefixesAreRefusedBeforeAllocation) {
  auto g = new_grid();
  g->tree().setValue({0, 0, 0}, 1.0f);
  g->insertMeta("spectrack_note", openvdb::StringMetadata("hello"));
  TempFile src("lengths.vdb");
  write_vdb(src.path, {g});
  std::string bytes;
  {
    std::ifstream is(src.path, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(is), {});
  }
  // The metadata entry is: name, type name "string", then the value's uint32 byte count.
  const size_t at = bytes.find("spectrack_note");
  ASSERT_NE(at, std::string::npos);
  const size_t value_len = at + std::string("spectrack_note").size() + 4 + std::string("string").size();
  // And the first grid descriptor starts with the uint32 length of the grid name.
  const size_t name_len = bytes.find("density") - 4;
  for (size_t off : {value_len, name_len}) {
    std::string bad = bytes;
    const uint32_t huge = 0x7ffffff0u;
    std::memcpy(&bad[off], &huge, 4);
    TempFile t("huge_length.vdb");
    std::ofstream(t.path, std::ios::binary) << bad;
    const std::string msg = error_of([&] { spectrack::load_float_grid(t.path, "density", -1, "test"); });
    EXPECT_TRUE(contains(msg, "corrupt")) << msg;
  }
}

// ---- lookups and majorants --------------------------------------------------------------------

TEST(VolumeSample, TrilinearMatchesOpenVdbBoxSampler) {
  const std::string path = data_path("wdas_cloud_sixteenth.vdb");
  REQUIRE_FILE(path);
  const GridData g = spectrack::load_float_grid(path, "density", -1, "test");
  const auto ref = read_vdb(path, "density");
  auto acc = ref->getConstAccessor();
  std::mt19937 rng(2024);
  int nonzero = 0;
  for (int i = 0; i < 1000; ++i) {
    double p[3];
    for (int a = 0; a < 3; ++a) {
      std::uniform_real_distribution<double> u(g.index_min[a] - 3.0, g.index_max[a] + 3.0);
      p[a] = u(rng);
    }
    const float v = spectrack::sample_index_trilinear(g, p[0], p[1], p[2]);
    const float r = openvdb::tools::BoxSampler::sample(acc, openvdb::Vec3R(p[0], p[1], p[2]));
    EXPECT_NEAR(v, r, 1e-5 * std::max(std::abs(r), 1e-3f)) << p[0] << " " << p[1] << " " << p[2];
    nonzero += r > 0;
  }
  EXPECT_GT(nonzero, 50);
}

TEST(VolumeMajorant, BoundsDisneyCloud) {
  const std::string path = data_path("wdas_cloud_sixteenth.vdb");
  REQUIRE_FILE(path);
  const GridData g = spectrack::load_float_grid(path, "density", -1, "test");
  const auto t0 = std::chrono::steady_clock::now();
  const MajorantGrid m = spectrack::build_majorant_grid(g, 8);
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  std::cout << "[ info ] majorant build, Disney cloud, cell 8, " << m.dims[0] << "x" << m.dims[1] << "x" << m.dims[2]
            << " cells: " << ms << " ms\n";
  EXPECT_EQ(m.dims, (std::array<int, 3>{16, 11, 20}));
  const auto ref = read_vdb(path, "density");
  check_majorant(g, *ref, 8, 20000, {});
}

TEST(VolumeMajorant, BoundsSyntheticShellAndSheet) {
  std::vector<openvdb::Coord> hot;
  auto grid = shell_and_sheet(&hot);
  TempFile t("shell.vdb");
  write_vdb(t.path, {grid});
  const GridData g = spectrack::load_float_grid(t.path, "density", -1, "test");
  for (int cell : {4, 8, 16}) {
    const int narrow_violations = check_majorant(g, *grid, cell, 20000, hot);
    EXPECT_GT(narrow_violations, 0) << "a bound without the interpolation apron went undetected, cell " << cell;
  }
}

TEST(VolumeMajorant, BoundIsTight) {
  std::vector<openvdb::Coord> hot;
  auto grid = shell_and_sheet(&hot);
  TempFile t("tight.vdb");
  write_vdb(t.path, {grid});
  const GridData g = spectrack::load_float_grid(t.path, "density", -1, "test");
  const MajorantGrid m = spectrack::build_majorant_grid(g, 8);
  float expect = g.value_max * (1.0f + 1e-5f);
  expect += 1e-30f;
  EXPECT_EQ(*std::max_element(m.dmax.begin(), m.dmax.end()), expect);
  // Every cell's bound is its support maximum, recomputed here through OpenVDB.
  auto acc = grid->getConstAccessor();
  std::mt19937 rng(5);
  EXPECT_FLOAT_EQ(spectrack::sample_index_trilinear(g, 12.5, 4.5, 4.5), 0.7f);  // inside the active tile
  for (int i = 0; i < 60; ++i) {
    std::array<int, 3> c{int(rng() % m.dims[0]), int(rng() % m.dims[1]), int(rng() % m.dims[2])};
    if (i == 0) c = {(12 - m.origin[0]) / 8, (4 - m.origin[1]) / 8, (4 - m.origin[2]) / 8};
    float hi = 0, lo = INFINITY;
    for (int z = 0; z <= 8; ++z)
      for (int y = 0; y <= 8; ++y)
        for (int x = 0; x <= 8; ++x) {
          const float v = acc.getValue(openvdb::Coord(m.origin[0] + c[0] * 8 + x, m.origin[1] + c[1] * 8 + y,
                                                      m.origin[2] + c[2] * 8 + z));
          hi = std::max(hi, v);
          lo = std::min(lo, v);
        }
    float e = hi * (1.0f + 1e-5f);
    if (e > 0) e += 1e-30f;
    EXPECT_EQ(m.dmax[size_t(cell_index(m, c))], e);
    EXPECT_EQ(m.dmin[size_t(cell_index(m, c))], lo * (1.0f - 1e-5f));
  }
}

TEST(VolumeMajorant, DisneyCloudHasPositiveMinorants) {
  const std::string path = data_path("wdas_cloud_sixteenth.vdb");
  REQUIRE_FILE(path);
  const GridData g = spectrack::load_float_grid(path, "density", -1, "test");
  const MajorantGrid m = spectrack::build_majorant_grid(g, 4);
  size_t positive = 0;
  for (float v : m.dmin) positive += v > 0;
  EXPECT_GT(positive, 0u);
}

// ---- NanoVDB files ----------------------------------------------------------------------------

namespace {

void expect_same_lookups(const GridData& a, const GridData& b, int n) {
  std::mt19937 rng(31);
  for (int i = 0; i < n; ++i) {
    double p[3];
    for (int k = 0; k < 3; ++k) {
      std::uniform_real_distribution<double> u(a.index_min[k] - 2.0, a.index_max[k] + 2.0);
      p[k] = u(rng);
    }
    ASSERT_EQ(spectrack::sample_index_trilinear(a, p[0], p[1], p[2]),
              spectrack::sample_index_trilinear(b, p[0], p[1], p[2]));
  }
}

// Writes a one-grid .nvdb with the given codec, encoding through OpenVDB's codecs (the same
// byte layout as NanoVDB's writer: a uint64 size, then the compressed bytes).
void write_nvdb(const std::string& path, const nanovdb::GridHandle<nanovdb::HostBuffer>& h, nanovdb::io::Codec codec) {
  const auto* grid = h.grid<float>();
  std::ostringstream payload;
  const char* bytes = reinterpret_cast<const char*>(h.data());
  if (codec == nanovdb::io::Codec::ZIP) {
    openvdb::io::zipToStream(payload, bytes, h.size());
  } else if (codec == nanovdb::io::Codec::BLOSC) {
    openvdb::io::bloscToStream(payload, bytes, sizeof(float), h.size() / sizeof(float));
  } else {
    payload.write(bytes, std::streamsize(h.size()));
  }
  nanovdb::io::Header header(codec);
  header.gridCount = 1;
  nanovdb::io::GridMetaData meta(h.size(), codec, *grid);
  meta.fileSize = payload.str().size();
  std::ofstream os(path, std::ios::binary);
  os.write(reinterpret_cast<const char*>(&header), sizeof(header));
  meta.write(os);
  os << payload.str();
}

}  // namespace

TEST(VolumeNanoVdb, DerivedDisneyCloudMatchesVdb) {
  const std::string vdb = data_path("wdas_cloud_sixteenth.vdb");
  const std::string nvdb = data_path("derived/wdas_cloud_sixteenth.nvdb");
  REQUIRE_FILE(vdb);
  REQUIRE_FILE(nvdb);
  const GridData a = spectrack::load_float_grid(vdb, "density", -1, "test");
  const GridData b = spectrack::load_float_grid(nvdb, "density", -1, "test");
  EXPECT_EQ(a.index_min, b.index_min);
  EXPECT_EQ(a.index_max, b.index_max);
  EXPECT_EQ(a.value_max, b.value_max);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) EXPECT_NEAR(a.index_to_world[r][c], b.index_to_world[r][c], 1e-9);
  expect_same_lookups(a, b, 1000);
  const std::vector<std::string> l = spectrack::list_grids(nvdb);
  ASSERT_EQ(l.size(), 1u);
  EXPECT_TRUE(contains(l[0], "density (float")) << l[0];
}

TEST(VolumeNanoVdb, BloscUnnamedSmoke) {
  const std::string path = data_path("smoke1-blosc.nvdb");
  REQUIRE_FILE(path);
  try {
    testing::internal::CaptureStderr();
    const GridData g = spectrack::load_float_grid(path, "density", -1, "test");
    const std::string warning = testing::internal::GetCapturedStderr();
    EXPECT_TRUE(contains(warning, "no name")) << warning;
    EXPECT_EQ(g.index_min, (std::array<int, 3>{1, 2, 1}));
    EXPECT_EQ(g.index_max, (std::array<int, 3>{111, 223, 112}));
    EXPECT_GT(g.value_max, 5.0f);
    std::cout << "[ info ] smoke1-blosc.nvdb loaded, values up to " << g.value_max << "\n";
  } catch (const spectrack::Error& e) {
    testing::internal::GetCapturedStderr();
    EXPECT_TRUE(contains(e.what(), "BLOSC")) << e.what();
  }
}

TEST(VolumeNanoVdb, CodecsRoundTripAndCorruption) {
  std::vector<openvdb::Coord> hot;
  auto grid = shell_and_sheet(&hot);
  const auto handle = nanovdb::openToNanoVDB(*grid, nanovdb::StatsMode::Default, nanovdb::ChecksumMode::Full);
  TempFile src("src.vdb");
  write_vdb(src.path, {grid});
  const GridData ref = spectrack::load_float_grid(src.path, "density", -1, "test");
  for (auto codec : {nanovdb::io::Codec::NONE, nanovdb::io::Codec::ZIP, nanovdb::io::Codec::BLOSC}) {
    TempFile t("codec.nvdb");
    write_nvdb(t.path, handle, codec);
    const GridData g = spectrack::load_float_grid(t.path, "density", -1, "test");
    EXPECT_EQ(g.index_min, ref.index_min);
    EXPECT_EQ(g.index_max, ref.index_max);
    expect_same_lookups(ref, g, 500);
  }
  // Truncated and bit-flipped copies of an uncompressed file are refused cleanly.
  TempFile plain("plain.nvdb");
  write_nvdb(plain.path, handle, nanovdb::io::Codec::NONE);
  std::string bytes;
  {
    std::ifstream is(plain.path, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(is), {});
  }
  for (size_t cut : {size_t(10), size_t(100), bytes.size() / 2, bytes.size() - 1}) {
    TempFile t("cut.nvdb");
    std::ofstream(t.path, std::ios::binary) << bytes.substr(0, cut);
    const std::string msg = error_of([&] { spectrack::load_float_grid(t.path, "density", -1, "test"); });
    EXPECT_TRUE(contains(msg, t.path)) << msg;
  }
  // The grid starts after the 16-byte segment header, a 176-byte grid header and the name.
  const size_t grid_start = 16 + 176 + 8;
  for (size_t at : {grid_start + 40, grid_start + 700, bytes.size() / 2, bytes.size() - 100}) {
    std::string flipped = bytes;
    for (size_t i = at; i < at + 16; ++i) flipped[i] = char(~flipped[i]);
    TempFile t("flip.nvdb");
    std::ofstream(t.path, std::ios::binary) << flipped;
    const std::string msg = error_of([&] { spectrack::load_float_grid(t.path, "density", -1, "test"); });
    EXPECT_TRUE(contains(msg, "corrupt")) << "flipped at " << at << ": " << msg;
  }
  // A node offset moved off NanoVDB's 32-byte alignment (leaf, lower, upper, root) is refused
  // before a node reference is formed from it (fuzz_nvdb found the root case; UBSan reports it).
  const size_t tree_start = grid_start + sizeof(nanovdb::GridData);
  for (int level = 0; level < 4; ++level) {
    std::string moved = bytes;
    uint64_t off = 0;
    std::memcpy(&off, &moved[tree_start + 8 * size_t(level)], 8);
    off += 8;
    std::memcpy(&moved[tree_start + 8 * size_t(level)], &off, 8);
    TempFile t("misaligned.nvdb");
    std::ofstream(t.path, std::ios::binary) << moved;
    const std::string msg = error_of([&] { spectrack::load_float_grid(t.path, "density", -1, "test"); });
    EXPECT_TRUE(contains(msg, "misaligned")) << "level " << level << ": " << msg;
  }
}

// A BLOSC chunk whose byte count is smaller than blosc's 16-byte header is refused before its
// header is read (fuzz_nvdb found a 1-byte chunk whose header was read 12 bytes past the buffer;
// ASan reports the old code here).
TEST(VolumeNanoVdb, ShortBloscChunkRefused) {
  std::vector<openvdb::Coord> hot;
  auto grid = shell_and_sheet(&hot);
  const auto handle = nanovdb::openToNanoVDB(*grid, nanovdb::StatsMode::Default, nanovdb::ChecksumMode::Full);
  TempFile blosc("blosc.nvdb");
  write_nvdb(blosc.path, handle, nanovdb::io::Codec::BLOSC);
  std::string bytes;
  {
    std::ifstream is(blosc.path, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(is), {});
  }
  // The first chunk's uint64 byte count follows the 16-byte segment header, the 176-byte grid
  // header and the name "density".
  const size_t chunk_at = 16 + 176 + 8;
  ASSERT_GT(bytes.size(), chunk_at + 8 + 16);
  for (uint64_t n : {uint64_t(1), uint64_t(4), uint64_t(15)}) {
    std::string shortened = bytes;
    std::memcpy(&shortened[chunk_at], &n, 8);
    TempFile t("short_chunk.nvdb");
    std::ofstream(t.path, std::ios::binary) << shortened;
    const std::string msg = error_of([&] { spectrack::load_float_grid(t.path, "density", -1, "test"); });
    EXPECT_TRUE(contains(msg, "shorter than its header")) << "chunk of " << n << " bytes: " << msg;
    EXPECT_TRUE(contains(msg, t.path)) << msg;
  }
}

TEST(VolumeNanoVdb, ErrorsMatchVdb) {
  const std::string path = data_path("derived/densityAndHeat.nvdb");
  REQUIRE_FILE(path);
  const std::string msg = error_of([&] { spectrack::load_float_grid(path, "smoke", -1, "test"); });
  EXPECT_TRUE(contains(msg, "density (float")) << msg;
  const GridData g = spectrack::load_float_grid(path, "heat", -1, "test");
  EXPECT_FALSE(g.empty);
}

// A float grid with varied values, an active 8^3 tile and an active 128^3 tile, under a rotated,
// scaled and translated map: the source the NanoVDB value types below are written from.
openvdb::FloatGrid::Ptr quantizable_grid() {
  auto g = new_grid();
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(0.0f, 2.0f);
  auto acc = g->getAccessor();
  for (int z = -20; z < 20; ++z)
    for (int y = -12; y < 20; ++y)
      for (int x = -20; x < 21; ++x)
        if ((x * 7 + y * 3 + z) % 5) acc.setValue(openvdb::Coord(x, y, z), u(rng));
  g->tree().addTile(1, openvdb::Coord(64, 0, 0), 0.75f, true);
  g->tree().addTile(2, openvdb::Coord(256, 0, 0), 0.25f, true);
  openvdb::math::Mat4d m = openvdb::math::Mat4d::identity();
  m.preRotate(openvdb::math::Y_AXIS, 0.4);
  m.preScale(openvdb::Vec3d(0.05, 0.04, 0.05));
  m.postTranslate(openvdb::Vec3d(1.5, -2.0, 0.25));
  g->setTransform(openvdb::math::Transform::createLinearTransform(m));
  return g;
}

template <typename BuildT>
std::string write_nvdb_as(const openvdb::FloatGrid& g, const std::string& path,
                          nanovdb::ChecksumMode cs = nanovdb::ChecksumMode::Full) {
  if constexpr (std::is_same_v<BuildT, double>) {
    openvdb::DoubleGrid d(std::make_shared<openvdb::DoubleTree>(g.tree()));
    static_cast<openvdb::MetaMap&>(d) = static_cast<const openvdb::MetaMap&>(g);
    d.setTransform(g.transform().copy());
    nanovdb::io::writeGrid(path, nanovdb::openToNanoVDB<nanovdb::HostBuffer, openvdb::DoubleTree, double>(
                                     d, nanovdb::StatsMode::Default, cs));
  } else {
    nanovdb::io::writeGrid(path, nanovdb::openToNanoVDB<nanovdb::HostBuffer, openvdb::FloatTree, BuildT>(
                                     g, nanovdb::StatsMode::Default, cs));
  }
  return path;
}

// Every active value of src read back from the loaded grid within tol, the same active voxel
// count, box, value range within tol and the same index-to-world map.
void expect_loaded_as(const openvdb::FloatGrid& src, const GridData& got, float tol, const std::string& what) {
  const auto* ng = got.handle.grid<float>();
  ASSERT_NE(ng, nullptr) << what;
  auto acc = ng->getAccessor();
  EXPECT_EQ(ng->activeVoxelCount(), src.activeVoxelCount()) << what;
  float worst = 0.0f, lo = 1e30f, hi = -1e30f;
  for (auto v = src.tree().cbeginValueOn(); v; ++v) {
    const openvdb::Coord c = v.getCoord();  // a tile's first voxel; its value fills the tile
    const float read = acc.getValue(nanovdb::Coord(c.x(), c.y(), c.z()));
    EXPECT_TRUE(acc.isActive(nanovdb::Coord(c.x(), c.y(), c.z()))) << what << " at " << c;
    worst = std::max(worst, std::abs(read - *v));
    lo = std::min(lo, *v), hi = std::max(hi, *v);
  }
  EXPECT_LE(worst, tol) << what;
  EXPECT_NEAR(got.value_min, lo, tol) << what;
  EXPECT_NEAR(got.value_max, hi, tol) << what;
  const openvdb::CoordBBox box = src.evalActiveVoxelBoundingBox();
  EXPECT_EQ(got.index_min, (std::array<int, 3>{box.min().x(), box.min().y(), box.min().z()})) << what;
  EXPECT_EQ(got.index_max, (std::array<int, 3>{box.max().x(), box.max().y(), box.max().z()})) << what;
  const openvdb::math::Mat4d m = src.transform().baseMap()->getAffineMap()->getMat4();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(got.index_to_world[r][c], m(c, r), 1e-12) << what;
    EXPECT_NEAR(got.index_to_world[r][3], m(3, r), 1e-12) << what;
  }
}

// Double and quantized NanoVDB grids (Fp4, Fp8, Fp16, FpN) are read as float grids: every active
// voxel and tile where the source has it, within the quantization step (a leaf's values span at
// most 2: Fp4's half step 2 / 30, Fp8's 2 / 510, Fp16's 2 / 131070, FpN's tolerance for fog
// volumes, 0.01; doubles written from floats come back exactly), with full and partial checksums.
TEST(VolumeNanoVdb, DoubleAndQuantizedGridsAreReadAsFloat) {
  const auto g = quantizable_grid();
  const std::string dir = st_test::temp_dir("nvdb_quantized");
  struct Case {
    const char* name;
    std::string (*write)(const openvdb::FloatGrid&, const std::string&, nanovdb::ChecksumMode);
    float tol;
  };
  const Case cases[] = {{"fp4", write_nvdb_as<nanovdb::Fp4>, 2.0f / 30 + 1e-6f},
                        {"fp8", write_nvdb_as<nanovdb::Fp8>, 2.0f / 510 + 1e-6f},
                        {"fp16", write_nvdb_as<nanovdb::Fp16>, 2.0f / 131070 + 1e-6f},
                        {"fpn", write_nvdb_as<nanovdb::FpN>, 0.01f + 1e-6f},
                        {"double", write_nvdb_as<double>, 0.0f},
                        {"float", write_nvdb_as<float>, 0.0f}};
  for (const Case& c : cases)
    for (const auto cs : {nanovdb::ChecksumMode::Full, nanovdb::ChecksumMode::Partial}) {
      const std::string path = c.write(*g, dir + "/" + c.name + ".nvdb", cs);
      expect_loaded_as(*g, spectrack::load_float_grid(path, "density", -1, "test"), c.tol, c.name);
    }
  // the twin: a coarser quantization than a case claims is seen
  const GridData fp4 = spectrack::load_float_grid(write_nvdb_as<nanovdb::Fp4>(*g, dir + "/twin.nvdb"), "density", -1, "t");
  auto acc = fp4.handle.grid<float>()->getAccessor();
  float worst = 0.0f;
  for (auto v = g->tree().cbeginValueOn(); v; ++v)
    worst = std::max(worst, std::abs(acc.getValue(nanovdb::Coord(v.getCoord().x(), v.getCoord().y(), v.getCoord().z())) - *v));
  EXPECT_GT(worst, 2.0f / 510) << "Fp4 must quantize more coarsely than Fp8's tolerance";
}

// A quantized grid is refused before it is decoded where its float grid cannot fit the host's
// memory (an FpN leaf of 1-bit values grows about 13 times; a compressed file 1024 times first).
TEST(VolumeNanoVdb, QuantizedGridLargerThanMemoryIsRefusedBeforeDecoding) {
  const auto g = quantizable_grid();
  const std::string dir = st_test::temp_dir("nvdb_decode_memory");
  const std::string path = write_nvdb_as<nanovdb::FpN>(*g, dir + "/fpn.nvdb");
  const size_t float_bytes = spectrack::load_float_grid(path, "density", -1, "test").handle.size();
  std::string msg;
  {
    st_test::ScopedEnv env("SPECTRACK_HOST_MEMORY", std::to_string(float_bytes).c_str());
    msg = error_of([&] { spectrack::load_float_grid(path, "density", -1, "test"); });
  }
  EXPECT_TRUE(contains(msg, "fpn.nvdb")) << msg;
  EXPECT_TRUE(contains(msg, "grid \"density\" (" + std::to_string(g->tree().leafCount()) + " leaves) read as float needs about"))
      << msg;
  EXPECT_TRUE(contains(msg, "MiB are available (SPECTRACK_HOST_MEMORY says so)")) << msg;
  // the estimate holds the decoded float grid and the OpenVDB tree it is built from, not more
  const size_t at = msg.find("needs about ");
  ASSERT_NE(at, std::string::npos);
  const double estimate = std::stod(msg.substr(at + 12)) * 1048576.0;
  EXPECT_GT(estimate, 1.5 * double(float_bytes));
  EXPECT_LT(estimate, 3.0 * double(float_bytes));
  // the twin: just above the estimate, the grid is read
  st_test::ScopedEnv env("SPECTRACK_HOST_MEMORY", std::to_string(int64_t(estimate + 0.1 * 1048576.0)).c_str());
  EXPECT_NO_THROW(spectrack::load_float_grid(path, "density", -1, "test"));
  // any grid's bytes (a compressed one may claim 1024 times its size on disk) are checked first
  st_test::ScopedEnv small("SPECTRACK_HOST_MEMORY", "65536");
  const std::string float_path = write_nvdb_as<float>(*g, dir + "/float.nvdb");
  msg = error_of([&] { spectrack::load_float_grid(float_path, "density", -1, "test"); });
  EXPECT_TRUE(contains(msg, "float.nvdb: grid \"density\" needs about")) << msg;
}

// A double value that a float cannot hold is refused naming its voxel, as in a .vdb.
TEST(VolumeNanoVdb, DoubleValueBeyondAFloatIsRefusedByVoxel) {
  openvdb::initialize();
  openvdb::DoubleGrid d(0.0);
  d.setName("density");
  d.setGridClass(openvdb::GRID_FOG_VOLUME);
  d.tree().setValue(openvdb::Coord(3, -4, 5), 1e300);
  const std::string path = st_test::temp_dir("nvdb_double_big") + "/big.nvdb";
  nanovdb::io::writeGrid(path, nanovdb::openToNanoVDB<nanovdb::HostBuffer, openvdb::DoubleTree, double>(d));
  const std::string msg = error_of([&] { spectrack::load_float_grid(path, "density", -1, "test"); });
  EXPECT_TRUE(contains(msg, "value 1e+300 at active voxel (3, -4, 5) is beyond a 32-bit float's range")) << msg;
}

// The bytes of an uncompressed single-grid .nvdb: the grid is the file's tail.
struct NvdbBytes {
  std::string bytes;
  size_t grid_at = 0;
  explicit NvdbBytes(const std::string& path, uint64_t grid_size) {
    std::ifstream in(path, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
    grid_at = bytes.size() - grid_size;
  }
  // (memcpy: a field of the grid need not be aligned in the file's bytes)
  template <typename T>
  T get(size_t off) const {
    T v;
    std::memcpy(&v, &bytes[grid_at + off], sizeof v);
    return v;
  }
  template <typename T>
  void set(size_t off, T v) { std::memcpy(&bytes[grid_at + off], &v, sizeof v); }
  void write(const std::string& path) const { std::ofstream(path, std::ios::binary) << bytes; }
};

// Damaged quantized grids are refused by name before NanoVDB's own code follows their offsets: an
// FpN leaf claiming 128 bits per value, a tree claiming one leaf more than it holds, a voxel count
// that is not the tree's (with no checksum to catch it).
TEST(VolumeNanoVdb, DamagedQuantizedGridsAreRefused) {
  const auto g = quantizable_grid();
  const std::string dir = st_test::temp_dir("nvdb_fpn_damaged");
  auto handle = nanovdb::openToNanoVDB<nanovdb::HostBuffer, openvdb::FloatTree, nanovdb::FpN>(*g);
  const uint64_t size = handle.size();
  nanovdb::io::writeGrid(dir + "/ok.nvdb", handle, nanovdb::io::Codec::NONE);
  const size_t tree = sizeof(nanovdb::GridData);
  const auto* td = reinterpret_cast<const nanovdb::TreeData<3>*>(handle.data() + tree);
  auto load = [&](const std::string& name) {
    return error_of([&] { spectrack::load_float_grid(dir + "/" + name, "density", -1, "test"); });
  };
  EXPECT_NO_THROW(spectrack::load_float_grid(dir + "/ok.nvdb", "density", -1, "test"));  // the twin

  NvdbBytes wide(dir + "/ok.nvdb", size);
  wide.set<uint8_t>(tree + td->mNodeOffset[0] + 15, uint8_t(7u << 5));  // the first leaf's flags: bit width 2^7
  wide.write(dir + "/wide.nvdb");
  EXPECT_TRUE(contains(load("wide.nvdb"), "corrupt NanoVDB grid (FpN leaf")) << load("wide.nvdb");

  NvdbBytes count(dir + "/ok.nvdb", size);
  const size_t leaves_at = tree + offsetof(nanovdb::TreeData<3>, mNodeCount);
  count.set<uint32_t>(leaves_at, count.get<uint32_t>(leaves_at) + 1);  // one leaf more
  count.write(dir + "/count.nvdb");
  EXPECT_TRUE(contains(load("count.nvdb"), "corrupt NanoVDB grid (node count")) << load("count.nvdb");

  auto unchecked = nanovdb::openToNanoVDB<nanovdb::HostBuffer, openvdb::FloatTree, nanovdb::Fp16>(
      *g, nanovdb::StatsMode::Default, nanovdb::ChecksumMode::Disable);
  reinterpret_cast<nanovdb::TreeData<3>*>(unchecked.data() + tree)->mVoxelCount += 1;
  nanovdb::io::writeGrid(dir + "/voxels.nvdb", unchecked, nanovdb::io::Codec::NONE);
  EXPECT_TRUE(contains(load("voxels.nvdb"), "disagree with the count stored in the grid")) << load("voxels.nvdb");

  // a review's findings: the root read before its offset was checked (an FpN grid's background),
  // and a node array at offset 0 that NanoVDB's checksum takes for the first node (Fp16 and float,
  // with full checksums)
  NvdbBytes far_root(dir + "/ok.nvdb", size);
  far_root.set<uint64_t>(tree + offsetof(nanovdb::TreeData<3>, mNodeOffset) + 3 * 8, uint64_t(1) << 40);
  far_root.write(dir + "/far_root.nvdb");
  EXPECT_TRUE(contains(load("far_root.nvdb"), "corrupt NanoVDB grid (root outside the grid")) << load("far_root.nvdb");
  for (const bool quantized : {true, false}) {
    auto full = quantized ? nanovdb::openToNanoVDB<nanovdb::HostBuffer, openvdb::FloatTree, nanovdb::Fp16>(
                                *g, nanovdb::StatsMode::Default, nanovdb::ChecksumMode::Full)
                          : nanovdb::openToNanoVDB<nanovdb::HostBuffer, openvdb::FloatTree, float>(
                                *g, nanovdb::StatsMode::Default, nanovdb::ChecksumMode::Full);
    nanovdb::io::writeGrid(dir + "/full.nvdb", full, nanovdb::io::Codec::NONE);
    NvdbBytes at0(dir + "/full.nvdb", full.size());
    at0.set<uint64_t>(tree + offsetof(nanovdb::TreeData<3>, mNodeOffset) + 1 * 8, uint64_t(0));  // the lower nodes
    at0.write(dir + "/at0.nvdb");
    const std::string m = load("at0.nvdb");
    EXPECT_TRUE(contains(m, "corrupt NanoVDB grid (node array")) << m;  // one check for every value type
  }

  // fuzz_nvdb's finding: `info` read a vector grid's index box through a root offset it had not
  // checked (a pointer far outside the buffer); now the offset is checked first
  auto v = openvdb::Vec3SGrid::create(openvdb::Vec3s(0.0f));
  v->setName("vel");
  v->tree().setValue(openvdb::Coord(1, 2, 3), openvdb::Vec3s(1, 2, 2));
  auto vh = nanovdb::openToNanoVDB(openvdb::GridBase::Ptr(v));
  nanovdb::io::writeGrid(dir + "/vel.nvdb", vh, nanovdb::io::Codec::NONE);
  EXPECT_NO_THROW(spectrack::inspect_volume(dir + "/vel.nvdb"));  // the twin
  NvdbBytes root(dir + "/vel.nvdb", vh.size());
  root.set<uint64_t>(tree + offsetof(nanovdb::TreeData<3>, mNodeOffset) + 3 * 8, uint64_t(1) << 60);
  root.write(dir + "/root.nvdb");
  const std::string info = error_of([&] { spectrack::inspect_volume(dir + "/root.nvdb"); });
  EXPECT_TRUE(contains(info, "corrupt NanoVDB grid (root outside the grid")) << info;
}

// `info` on a .nvdb of a quantized density and a vector grid: the density is usable, the vector
// grid is described and named as not a density (it does not fail the file).
TEST(VolumeNanoVdb, InfoDescribesQuantizedAndVectorGrids) {
  const auto g = quantizable_grid();
  auto v = openvdb::Vec3SGrid::create(openvdb::Vec3s(0.0f));
  v->setName("vel");
  v->tree().setValue(openvdb::Coord(1, 2, 3), openvdb::Vec3s(1, 2, 2));
  std::vector<nanovdb::GridHandle<nanovdb::HostBuffer>> handles;
  handles.push_back(nanovdb::openToNanoVDB<nanovdb::HostBuffer, openvdb::FloatTree, nanovdb::Fp16>(*g));
  handles.push_back(nanovdb::openToNanoVDB(openvdb::GridBase::Ptr(v)));
  const std::string path = st_test::temp_dir("nvdb_info_fp16") + "/two.nvdb";
  nanovdb::io::writeGrids(path, handles);
  const std::vector<spectrack::GridInfo> info = spectrack::inspect_volume(path);
  ASSERT_EQ(info.size(), 2u);
  EXPECT_EQ(info[0].type, "Float16");
  EXPECT_EQ(info[0].density_use, "yes (16-bit quantized values, read as 32-bit floats)");
  EXPECT_EQ(info[0].active_voxels, g->activeVoxelCount());
  EXPECT_TRUE(info[0].has_range);
  EXPECT_NEAR(info[0].value_max, 2.0, 1e-3);
  EXPECT_EQ(info[1].name, "vel");
  EXPECT_TRUE(contains(info[1].density_use, "no: value type Vec3f")) << info[1].density_use;
  EXPECT_EQ(info[1].active_voxels, 1u);
}

// A review's finding: the far-reach majorant keyed leaves by their stored origins, which a node
// without active values need not hold truly (nothing else reads them): a partial-checksum .nvdb
// whose empty lower node claims the origin of the dense one overwrote that leaf's extremes with 0,
// and the cells over density 1 read a majorant of 0. Leaves are keyed by their place in the tree.
TEST(VolumeNanoVdb, FarReachMajorantReadsLeavesAtTheirPlaces) {
  auto g = new_grid();
  for (int z = 0; z < 8; ++z)
    for (int y = 0; y < 8; ++y)
      for (int x = 0; x < 8; ++x) g->tree().setValue(openvdb::Coord(x, y, z), 1.0f);
  g->tree().touchLeaf(openvdb::Coord(128, 0, 0));  // an inactive leaf in a second lower node
  auto h = nanovdb::openToNanoVDB<nanovdb::HostBuffer, openvdb::FloatTree, float>(*g, nanovdb::StatsMode::Default,
                                                                                  nanovdb::ChecksumMode::Partial);
  const std::string dir = st_test::temp_dir("nvdb_far_reach_origin");
  nanovdb::io::writeGrid(dir + "/ok.nvdb", h, nanovdb::io::Codec::NONE);
  const size_t tree = sizeof(nanovdb::GridData);
  const auto* td = reinterpret_cast<const nanovdb::TreeData<3>*>(h.data() + tree);
  NvdbBytes bad(dir + "/ok.nvdb", h.size());
  // the second lower node's bbox minimum (its stored origin) moved onto the first's
  const size_t l1 = tree + td->mNodeOffset[1] + sizeof(nanovdb::NanoLower<float>);
  for (int a = 0; a < 3; ++a) bad.set<int32_t>(l1 + 4 * size_t(a), int32_t(0));
  bad.write(dir + "/bad.nvdb");
  for (const char* f : {"/ok.nvdb", "/bad.nvdb"}) {
    const GridData d = spectrack::load_float_grid(dir + f, "density", -1, "t");
    const MajorantGrid exact = spectrack::build_majorant_grid(d, 8, {4, 4, 4}, {}, std::numeric_limits<double>::infinity());
    const MajorantGrid leaf = spectrack::build_majorant_grid(d, 8, {4, 4, 4}, {}, 0.0);
    ASSERT_EQ(exact.dmax.size(), leaf.dmax.size());
    for (size_t i = 0; i < exact.dmax.size(); ++i) EXPECT_GE(leaf.dmax[i], exact.dmax[i]) << f << " cell " << i;
    EXPECT_GE(*std::max_element(leaf.dmax.begin(), leaf.dmax.end()), 1.0f) << f;
  }
}
