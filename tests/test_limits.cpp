// test_limits.cpp: coordinates past what the float kernels resolve, memory estimates that refuse
// before allocating, and the messages of the majorant-cell, temperature, environment-scale and
// blackbody-cutoff limits.
//
// Design: the coordinate and message cases pack the scene only (pack_scene runs every check
// before the device is touched); the memory cases shrink the host budget through
// SPECTRACK_HOST_MEMORY so that a small film or map shows the refusal without allocating much.
#include <gtest/gtest.h>

#include <cstdlib>

#include <openvdb/openvdb.h>

#include "image/image.h"
#include "integrator/memory_budget.h"
#include "integrator/renderer.h"
#include "scene/scene_pack.h"
#include "integrator/settings.h"
#include "test_util.h"
#include "volume/volume.h"

using namespace spectrack;
using namespace st_test;
using json = nlohmann::json;

namespace {

json base_scene() {
  return json{{"format", "spectrack-scene/1"},
              {"camera", {{"position", {0, 0, -4}}, {"look_at", {0, 0, 0}}}},
              {"film", {{"width", 8}, {"height", 8}, {"spp", 2}, {"output", "out.exr"}}},
              {"lights", json::array({{{"type", "environment"}, {"radiance", {1, 1, 1}}}})},
              {"media", json::array()}};
}

json box(double half) {
  return json{{"type", "homogeneous"},
              {"bounds", {{-half, -half, -half}, {half, half, half}}},
              {"sigma_a", {1, 1, 1}},
              {"sigma_s", {0, 0, 0}}};
}

PackedScene pack(const json& j, const std::string& dir) {
  const SceneDesc d = scene_from_json(j, dir);
  return pack_scene(d, resolve_settings(d, quiet_options()), PackOptions{});
}

std::string pack_error(const json& j, const std::string& dir) {
  return error_of([&] { pack(j, dir); });
}

// A 16^3 grid of voxel 1/16 (a unit cube) at the origin.
std::string small_vdb(const std::string& dir) {
  const std::string f = dir + "/cube.vdb";
  write_vdb(f, "density", openvdb::Coord(-8, -8, -8), openvdb::Coord(7, 7, 7), [](int, int, int) { return 1.0f; },
            1.0 / 16.0);
  return f;
}

}  // namespace

TEST(LimitsCoordinates, HugeBoxRefusedByItsBounds) {
  const std::string dir = temp_dir("limits_box");
  json j = base_scene();
  j["camera"]["position"] = {0, 0, 0};
  j["camera"]["look_at"] = {0, 0, 1};
  j["media"].push_back(box(3e38));
  const std::string e = pack_error(j, dir);
  EXPECT_NE(e.find("/media/0/bounds"), std::string::npos) << e;
  EXPECT_NE(e.find("2^60"), std::string::npos) << e;
}

TEST(LimitsCoordinates, InfiniteMediumStandInStillPacks) {
  const std::string dir = temp_dir("limits_inf");
  for (double half : {1e6, 1e17}) {
    json j = base_scene();
    j["camera"]["position"] = {0, 0, 0};
    j["camera"]["look_at"] = {0, 0, 1};
    j["media"].push_back(box(half));
    EXPECT_NO_THROW(pack(j, dir)) << half;
  }
  // and renders as what it stands for: an absorbing medium all around the camera shows nothing
  json j = base_scene();
  j["camera"]["position"] = {0, 0, 0};
  j["camera"]["look_at"] = {0, 0, 1};
  j["media"].push_back(box(1e17));
  const RenderResult r = Renderer(scene_from_json(j, dir), quiet_options()).render();
  for (float v : r.rgb) EXPECT_EQ(v, 0.0f);
}

TEST(LimitsCoordinates, CameraBeyondTheFloatRange) {
  const std::string dir = temp_dir("limits_cam");
  json j = base_scene();
  j["camera"]["position"] = {0, 0, -1e39};
  const std::string e = pack_error(j, dir);
  EXPECT_NE(e.find("/camera/position"), std::string::npos) << e;
  // far, but not past the float range: the float spacing there is coarser than the grid's voxels
  j["camera"]["position"] = {0, 0, -1e9};
  j["media"].push_back({{"type", "vdb"}, {"file", small_vdb(dir)}});
  const std::string e2 = pack_error(j, dir);
  EXPECT_NE(e2.find("/camera/position"), std::string::npos) << e2;
  EXPECT_NE(e2.find("1/16 of the medium's shortest voxel edge"), std::string::npos) << e2;
}

TEST(LimitsCoordinates, TranslatesThatLoseTheMedium) {
  const std::string dir = temp_dir("limits_tr");
  const std::string f = small_vdb(dir);
  for (double t : {1e39, 1e30, 1e12})
    for (bool framed : {false, true}) {  // a camera framed on the medium lies where the medium is
      json j = base_scene();
      if (framed) j["camera"] = {{"position", "auto"}, {"look_at", "media"}};
      j["media"].push_back({{"type", "vdb"}, {"file", f}, {"transform", {{"translate", {t, 0, 0}}}}});
      const std::string e = pack_error(j, dir);
      EXPECT_NE(e.find("/media/0/transform/translate"), std::string::npos) << t << (framed ? " framed" : "") << ": " << e;
      EXPECT_EQ(e.find("/camera"), std::string::npos) << t << (framed ? " framed" : "") << ": " << e;
    }
  json j = base_scene();  // a grid scaled below the float spacing where it sits
  j["media"].push_back({{"type", "vdb"}, {"file", f}, {"transform", {{"scale", 1e-9}, {"translate", {1, 0, 0}}}}});
  const std::string e = pack_error(j, dir);
  EXPECT_NE(e.find("/media/0/transform:"), std::string::npos) << e;
}

TEST(LimitsCoordinates, MajorantScaleBelowFloatResolution) {
  const std::string dir = temp_dir("limits_maj");
  json j = base_scene();
  json m = box(1);
  m["majorant_scale"] = 1e-30;
  j["media"].push_back(m);
  const std::string e = pack_error(j, dir);
  EXPECT_NE(e.find("/media/0/majorant_scale"), std::string::npos) << e;
  j["media"][0]["majorant_scale"] = 0.5;
  EXPECT_NO_THROW(pack(j, dir));
}

TEST(LimitsMemory, FilmRefusedBeforeAllocation) {
  const std::string dir = temp_dir("limits_film");
  json j = base_scene();
  j["film"]["width"] = 4096;
  j["film"]["height"] = 4096;
  j["film"]["spp"] = 1;
  j["media"].push_back(box(1));
  ScopedEnv env("SPECTRACK_HOST_MEMORY", "100000000");  // 95 MiB
  const std::string e = error_of([&] { Renderer(scene_from_json(j, dir), quiet_options()).render(); });
  EXPECT_NE(e.find("4096x4096 film"), std::string::npos) << e;
  EXPECT_NE(e.find("host memory"), std::string::npos) << e;
  // --path-slots at its maximum: the slots alone need gigabytes
  j["film"]["width"] = 512;
  j["film"]["height"] = 512;
  j["film"]["spp"] = 64;
  RenderOptions o = quiet_options();
  o.path_slots = 1 << 24;
  const std::string e2 = error_of([&] { Renderer(scene_from_json(j, dir), o).render(); });
  EXPECT_NE(e2.find("16777216 path slots"), std::string::npos) << e2;
}

TEST(LimitsMemory, EstimatePerPixelAndPerSlot) {
  RenderShape s;
  s.npix = 1000;
  s.film_layers = 3;
  const MemoryNeed n = render_memory(s);
  EXPECT_DOUBLE_EQ(n.film_device, 1000 * 3 * 32.0);
  s.path_slots = 1 << 24;  // --path-slots at its maximum
  s.path_bytes = 256;
  EXPECT_GT(render_memory(s).slots_device, 4e9);
}

TEST(LimitsMemory, EnvironmentMapRefusedBeforeItsPixels) {
  const std::string dir = temp_dir("limits_env");
  write_image(dir + "/env.exr", 512, 256, std::vector<float>(512 * 256 * 3, 0.5f), {});
  json j = base_scene();
  j["lights"] = json::array({{{"type", "environment"}, {"map", "env.exr"}}});
  ScopedEnv env("SPECTRACK_HOST_MEMORY", "1000000");
  const std::string e = pack_error(j, dir);
  EXPECT_NE(e.find("/lights/0/map"), std::string::npos) << e;
  EXPECT_NE(e.find("512x256 environment map"), std::string::npos) << e;
}

// SPECTRACK_HOST_MEMORY is a count of bytes, read strictly (1G would be 1 byte to strtod), and a
// refusal it causes says so.
TEST(LimitsMemory, HostMemorySettingIsReadStrictlyAndNamed) {
  for (const char* bad : {"1G", "abc", "nan", "-5", " 100", "1e9"}) {
    ScopedEnv env("SPECTRACK_HOST_MEMORY", bad);
    const std::string e = error_of([] { host_memory_available(); });
    EXPECT_NE(e.find(std::string("SPECTRACK_HOST_MEMORY: '") + bad + "'"), std::string::npos) << e;
  }
  ScopedEnv env("SPECTRACK_HOST_MEMORY", "1000000");
  EXPECT_EQ(host_memory_available(), 1e6);  // the twin: a count reads
  const std::string e = error_of([] { check_host_memory(2e6, "a test", "use less"); });
  EXPECT_NE(e.find("SPECTRACK_HOST_MEMORY says so"), std::string::npos) << e;
}

TEST(LimitsMessages, EnvironmentScaleBoundsTheProduct) {
  const std::string dir = temp_dir("limits_envscale");
  write_image(dir + "/dim.exr", 8, 4, std::vector<float>(8 * 4 * 3, 1e-6f), {});
  json j = base_scene();
  j["lights"] = json::array({{{"type", "environment"}, {"map", "dim.exr"}, {"scale", 1e24}}});
  EXPECT_NO_THROW(pack(j, dir));  // 1e24 x 1e-6 = 1e18, within the bound
  j["lights"][0]["scale"] = 1e30;
  std::string e = pack_error(j, dir);
  EXPECT_NE(e.find("times scale"), std::string::npos) << e;
  j["lights"][0]["scale"] = 1e39;
  e = pack_error(j, dir);
  EXPECT_NE(e.find("/lights/0/scale"), std::string::npos) << e;
  EXPECT_NE(e.find("largest float"), std::string::npos) << e;
}

TEST(LimitsMessages, ConstantBlackbodyBelowCutoffWarns) {
  const std::string dir = temp_dir("limits_bb");
  json j = base_scene();
  json m = box(1);
  m["emission"] = {{"type", "blackbody"}, {"temperature", 50}};
  j["media"].push_back(m);
  testing::internal::CaptureStderr();
  scene_from_json(j, dir);
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_NE(err.find("/media/0/emission/temperature"), std::string::npos) << err;
  EXPECT_NE(err.find("does not emit"), std::string::npos) << err;
}

TEST(LimitsMessages, TemperatureScaleBound) {
  const std::string dir = temp_dir("limits_ts");
  write_vdb_grids(dir + "/fire.vdb", openvdb::Coord(0, 0, 0), openvdb::Coord(3, 3, 3),
                  {{"density", [](int, int, int) { return 1.0f; }}, {"temperature", [](int, int, int) { return 2.0f; }}});
  json j = base_scene();
  j["media"].push_back({{"type", "vdb"},
                        {"file", "fire.vdb"},
                        {"sigma_a", {1, 1, 1}},
                        {"emission", {{"type", "blackbody"}, {"temperature_scale", -1e30}}}});
  const std::string e = pack_error(j, dir);
  EXPECT_NE(e.find("is not below 1e30"), std::string::npos) << e;
  EXPECT_EQ(e.find("beyond"), std::string::npos) << e;
}

TEST(LimitsMessages, MajorantCellAdvice) {
  const std::string dir = temp_dir("limits_cell");
  openvdb::initialize();
  auto write_two = [&](const std::string& path, int far) {
    auto grid = openvdb::FloatGrid::create(0.0f);
    grid->setName("density");
    grid->getAccessor().setValue(openvdb::Coord(0, 0, 0), 1.0f);
    grid->getAccessor().setValue(openvdb::Coord(far, far, far), 1.0f);
    openvdb::GridPtrVec grids{grid};
    openvdb::io::File file(path);
    file.write(grids);
    file.close();
  };
  write_two(dir + "/near.vdb", 4096);
  const std::string e = error_of([&] { build_majorant_grid(load_float_grid(dir + "/near.vdb", "density", -1, "t"), 2); });
  EXPECT_NE(e.find("use --majorant-cell 16 or larger"), std::string::npos) << e;
  write_two(dir + "/far.vdb", 1 << 20);
  const std::string e2 = error_of([&] { build_majorant_grid(load_float_grid(dir + "/far.vdb", "density", -1, "t"), 2); });
  EXPECT_NE(e2.find("even the largest cell edge, 1024"), std::string::npos) << e2;
  EXPECT_EQ(e2.find("larger cell"), std::string::npos) << e2;
  // motion blur's reach widens the box: the count and the advice include it (they once counted the
  // box alone, advising the cell already refused, and a count past 2^64 printed as 0)
  write_two(dir + "/small.vdb", 60);
  const GridData small = load_float_grid(dir + "/small.vdb", "density", -1, "t");
  EXPECT_NO_THROW(build_majorant_grid(small, 2));
  const std::string e3 = error_of([&] { build_majorant_grid(small, 2, {900, 900, 900}); });
  EXPECT_NE(e3.find("widened by the motion blur's reach of (900, 900, 900) voxels"), std::string::npos) << e3;
  EXPECT_NE(e3.find("needs 8.07e+08 majorant cells"), std::string::npos) << e3;  // (62 + 1800) / 2 = 931 an axis
  EXPECT_NE(e3.find("use --majorant-cell 4 or larger"), std::string::npos) << e3;  // 466^3 < 2^27
}

// A medium whose paths scatter about a million times or more (albedo near 1, many mean free paths
// across) with an unlimited max_depth is warned of: such a render runs for hours with no word. The
// twins: a max_depth, some absorption, or a small box give no warning.
TEST(LimitsMessages, MediaWhosePathsNeverEndAreWarnedOf) {
  const std::string dir = temp_dir("long_paths");
  auto pack_warnings = [&](double half, const std::array<double, 3>& sigma_a, int max_depth) {
    json j = {{"format", "spectrack-scene/1"},
              {"camera", {{"position", {0, 0, -4}}, {"look_at", {0, 0, 0}}}},
              {"film", {{"width", 4}, {"height", 4}, {"spp", 1}}},
              {"lights", {{{"type", "environment"}, {"radiance", {1, 1, 1}}}}},
              {"media", {{{"type", "homogeneous"}, {"bounds", {{-half, -half, -half}, {half, half, half}}},
                          {"sigma_s", {1, 1, 1}}, {"sigma_a", {sigma_a[0], sigma_a[1], sigma_a[2]}}}}}};
    if (max_depth >= 0) j["render"] = {{"max_depth", max_depth}};
    const SceneDesc d = scene_from_json(j, dir);
    testing::internal::CaptureStderr();
    pack_scene(d, resolve_settings(d, quiet_options()), PackOptions{});
    return testing::internal::GetCapturedStderr();
  };
  const std::string w = pack_warnings(1e4, {0, 0, 0}, -1);
  EXPECT_NE(w.find("/media/0: a path takes about 1.8e+08 scattering events here"), std::string::npos) << w;
  EXPECT_NE(w.find("set render.max_depth"), std::string::npos) << w;
  // one channel that does not absorb keeps its paths going: still warned
  EXPECT_NE(pack_warnings(2e4, {0.5, 0.5, 0}, -1).find("scattering events"), std::string::npos);
  EXPECT_EQ(pack_warnings(1.5e4, {0, 0, 0}, 1000), "");    // a depth cap
  EXPECT_EQ(pack_warnings(1.6e4, {0.01, 0.01, 0.01}, -1), "");  // about 100 events before absorption
  EXPECT_EQ(pack_warnings(100, {0, 0, 0}, -1), "");        // about 1.8e4 events
}
