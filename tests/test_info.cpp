// test_info.cpp: `spectrack info` on every file of ../shared/data/vdb (docs/cli.md, `info`): the world boxes
// it prints are checked against OpenVDB's own evalActiveVoxelBoundingBox through the grid's
// transform, and the malformed files fail cleanly (exit 1, the file and a reason named, no crash).
#include <openvdb/openvdb.h>

#include <algorithm>

#include "cli_util.h"

namespace {

using namespace st_cli;

// The JSON document of `info --json` (stdout and stderr are merged: it starts at the first '[').
json info_json(const Proc& p) {
  const size_t at = p.out.find("[\n");
  if (at == std::string::npos) return json();
  return json::parse(p.out.substr(at), nullptr, false);
}

std::vector<std::string> shared_volumes() {
  std::vector<std::string> out;
  for (auto& e : fs::recursive_directory_iterator(kShared)) {
    const std::string ext = e.path().extension().string();
    if (e.is_regular_file() && (ext == ".vdb" || ext == ".nvdb")) out.push_back(e.path().string());
  }
  std::sort(out.begin(), out.end());
  return out;
}

// bad-bbox-empty.vdb is no damage: a valid empty grid without file_bbox metadata (test_cli.cpp).
bool damaged(const std::string& f) {
  return f.find("openvdb-damaged") != std::string::npos && f.find("bad-bbox-empty") == std::string::npos;
}

void expect_near3(const json& got, const openvdb::Vec3d& want, const std::string& what) {
  ASSERT_TRUE(got.is_array() && got.size() == 3) << what << ": " << got.dump();
  for (int a = 0; a < 3; ++a)
    EXPECT_NEAR(got[a].get<double>(), want[a], 1e-9 * (1 + std::abs(want[a]))) << what << " axis " << a;
}

// Every grid of every .vdb: index and world boxes against OpenVDB, voxel count, voxel size.
TEST(CliInfo, EveryVdbMatchesOpenVdbBoxes) {
  openvdb::initialize();
  const auto files = shared_volumes();
  ASSERT_GT(files.size(), 10u) << kShared;
  int checked = 0;
  for (const std::string& f : files) {
    if (damaged(f) || fs::path(f).extension() != ".vdb") continue;
    SCOPED_TRACE(f);
    Proc p = run({"info", "--json", f});
    ASSERT_TRUE(p.exited && p.code == 0) << p.describe();
    json j = info_json(p);
    ASSERT_TRUE(j.is_array() && j.size() == 1) << p.out;
    const json& grids = j[0]["grids"];
    openvdb::io::File file(f);
    file.open(false);
    openvdb::GridPtrVecPtr ref = file.getGrids();
    file.close();
    ASSERT_EQ(grids.size(), ref->size());
    for (size_t i = 0; i < ref->size(); ++i) {
      const openvdb::GridBase& g = *(*ref)[i];
      const json& gi = grids[i];
      EXPECT_EQ(gi["name"].get<std::string>(), g.getName());
      EXPECT_EQ(gi["type"].get<std::string>(), g.valueType());
      EXPECT_EQ(gi["active_voxels"].get<uint64_t>(), g.activeVoxelCount());
      const openvdb::CoordBBox box = g.evalActiveVoxelBoundingBox();
      EXPECT_EQ(gi["empty"].get<bool>(), box.empty());
      expect_near3(gi["voxel_size"], g.voxelSize(), "voxel size");
      if (box.empty()) continue;
      const openvdb::BBoxd w = g.transform().indexToWorld(box);
      expect_near3(gi["world_bbox"][0], w.min(), g.getName() + " world min");
      expect_near3(gi["world_bbox"][1], w.max(), g.getName() + " world max");
      expect_near3(gi["index_bbox"][0], box.min().asVec3d(), "index min");
      expect_near3(gi["index_bbox"][1], box.max().asVec3d(), "index max");
      if (g.isType<openvdb::FloatGrid>()) {
        EXPECT_GT(gi["nanovdb_bytes"].get<int64_t>(), 0);
        EXPECT_TRUE(gi["value_range"].is_array());
      }
      ++checked;
    }
  }
  EXPECT_GE(checked, 10);
}

// .nvdb: the converted files agree with their sources; the BLOSC file has smoke1's index box.
TEST(CliInfo, NanoVdbFilesAgreeWithTheirSources) {
  const std::vector<std::pair<std::string, std::string>> pairs = {
      {"derived/smoke1.nvdb", "smoke1.vdb"},
      {"derived/wdas_cloud_sixteenth.nvdb", "wdas_cloud_sixteenth.vdb"},
      {"derived/densityAndHeat.nvdb", "usd/densityAndHeat.vdb"}};
  for (auto& [nv, v] : pairs) {
    SCOPED_TRACE(nv);
    Proc a = run({"info", "--json", kShared + "/" + nv, kShared + "/" + v});
    ASSERT_TRUE(a.exited && a.code == 0) << a.describe();
    json j = info_json(a);
    ASSERT_EQ(j.size(), 2u) << a.out;
    ASSERT_EQ(j[0]["grids"].size(), j[1]["grids"].size());
    for (size_t i = 0; i < j[0]["grids"].size(); ++i) {
      const json& n = j[0]["grids"][i];
      const json& o = j[1]["grids"][i];
      EXPECT_EQ(n["index_bbox"], o["index_bbox"]);
      for (int c = 0; c < 2; ++c)
        for (int ax = 0; ax < 3; ++ax)
          EXPECT_NEAR(n["world_bbox"][c][ax].get<double>(), o["world_bbox"][c][ax].get<double>(), 1e-4);
      EXPECT_EQ(n["active_voxels"], o["active_voxels"]);
      if (o["value_range"].is_array() && n["value_range"].is_array()) {
        EXPECT_NEAR(n["value_range"][1].get<double>(), o["value_range"][1].get<double>(), 1e-6);
      }
    }
  }
  Proc b = run({"info", "--json", kShared + "/smoke1-blosc.nvdb"});
  ASSERT_TRUE(b.exited && b.code == 0) << b.describe();
  json j = info_json(b);
  EXPECT_EQ(j[0]["grids"][0]["index_bbox"], json::parse("[[1,2,1],[111,223,112]]")) << b.out;
  EXPECT_EQ(j[0]["grids"][0]["active_voxels"].get<uint64_t>(), 1049275u);
}

// The table names the grids, the boxes and smoke1's translated world box.
TEST(CliInfo, TableShowsTheWorldBox) {
  Proc p = run({"info", kShared + "/smoke1.vdb"});
  ASSERT_TRUE(p.exited && p.code == 0) << p.describe();
  for (const char* w : {"\"density\"", "float", "world bbox", "index bbox", "voxel size", "active voxels", "1049275",
                        "value range", "as NanoVDB", "MiB"})
    EXPECT_THAT(p.out, HasSubstr(w)) << p.out;
  // level sets and vector grids are listed, with why they are no density
  Proc q = run({"info", kShared + "/levelset/sphere.vdb", kShared + "/oiio/openvdb/sphereCd.vdb"});
  ASSERT_TRUE(q.exited && q.code == 0) << q.describe();
  EXPECT_THAT(q.out, HasSubstr("level set")) << q.out;
  EXPECT_THAT(q.out, HasSubstr("vec3s")) << q.out;
}

// Malformed, missing and foreign files: exit 1 naming the file and a reason, never a crash; the
// good files given alongside are still printed.
TEST(CliInfo, BadFilesFailCleanly) {
  std::vector<std::string> bad;
  for (const std::string& f : shared_volumes())
    if (damaged(f)) bad.push_back(f);
  ASSERT_GE(bad.size(), 6u);
  const std::string dir = test_dir();
  std::ofstream(dir + "/garbage.vdb") << "not a vdb at all";
  std::ofstream(dir + "/garbage.nvdb") << "not a nanovdb file";
  bad.push_back(dir + "/garbage.vdb");
  bad.push_back(dir + "/garbage.nvdb");
  bad.push_back(dir + "/missing.vdb");
  bad.push_back(dir + "/image.png");
  std::ofstream(dir + "/image.png") << "png";
  for (const std::string& f : bad) {
    SCOPED_TRACE(f);
    Proc p = run({"info", f});
    expect_error_exit(p);
    EXPECT_THAT(p.out, HasSubstr("error: " + f)) << p.out;
  }
  Proc both = run({"info", "--json", dir + "/garbage.vdb", kShared + "/oiio/openvdb/sphere.vdb"});
  expect_error_exit(both);
  EXPECT_THAT(both.out, HasSubstr("\"error\"")) << both.out;
  EXPECT_THAT(both.out, HasSubstr("\"grids\"")) << both.out;
}

// A scene: media boxes through the medium transform, optical depths, lights, the framed camera.
TEST(CliInfo, SceneShowsMediaLightsAndCamera) {
  const std::string dir = test_dir();
  json s = vdb_scene(kShared + "/smoke1.vdb");
  s["media"][0]["transform"] = {{"translate", {100, 0, 0}}};
  s["media"][0]["density_scale"] = 2.0;
  s["camera"]["look_at"] = "media";
  s["camera"]["fit"] = 1.1;
  const std::string scene = write_scene(dir, "s.json", s);
  Proc p = run({"info", "--json", scene});
  ASSERT_TRUE(p.exited && p.code == 0) << p.describe();
  json j = info_json(p);
  const json& m = j[0]["media"][0];
  // smoke1 is centred near (-7.1, 40.7, 0.7); translated by +100 in x
  const double cx = 0.5 * (m["world_bbox"][0][0].get<double>() + m["world_bbox"][1][0].get<double>());
  const double cy = 0.5 * (m["world_bbox"][0][1].get<double>() + m["world_bbox"][1][1].get<double>());
  EXPECT_NEAR(cx, 92.9, 1.0) << m.dump();
  EXPECT_NEAR(cy, 40.7, 1.0) << m.dump();
  EXPECT_GT(m["optical_depth_diagonal_max"][0].get<double>(), m["optical_depth_voxel_max"][0].get<double>());
  EXPECT_NEAR(m["sigma_t_max"][0].get<double>(), 2.0 * m["density_range"][1].get<double>(), 1e-6);
  EXPECT_EQ(j[0]["lights"].size(), 1u);
  EXPECT_TRUE(j[0]["camera"]["framed"].get<bool>());
  EXPECT_TRUE(j[0]["camera"]["media_in_view"][0].get<bool>()) << j.dump();
  EXPECT_NEAR(j[0]["camera"]["look_at"][0].get<double>(), cx, 1e-6);
  Proc t = run({"info", scene});
  ASSERT_TRUE(t.exited && t.code == 0) << t.describe();
  for (const char* w : {"medium \"cloud\"", "world bbox", "optical depth", "light", "camera perspective (framed)"})
    EXPECT_THAT(t.out, HasSubstr(w)) << t.out;
  // a scene of another name, as render reads it
  Proc txt = run({"info", write_scene(dir, "s.txt", s)});
  EXPECT_TRUE(txt.exited && txt.code == 0) << txt.describe();
  EXPECT_THAT(txt.out, HasSubstr("s.txt: scene")) << txt.out;
  // a scene error is named like render's
  s["media"][0]["sigma_x"] = 1;
  Proc e = run({"info", write_scene(dir, "bad.json", s)});
  expect_error_exit(e);
  EXPECT_THAT(e.out, HasSubstr("bad.json: /media/0/sigma_x")) << e.out;
}

// A scene that render refuses for its data (a grid the medium names and the file lacks, a number
// the kernels' floats cannot hold) is refused by info with render's message (exit 1, "renders":
// false in --json); the same scene without the fault passes. The camera's lens and shutter are shown.
TEST(CliInfo, SceneRefusedAsRenderRefusesIt) {
  const std::string dir = test_dir();
  const json base = vdb_scene(kShared + "/smoke1.vdb");
  struct Fault {
    const char* name;
    json medium_patch;
    const char* message;
  };
  const Fault faults[] = {
      {"colour_grid", {{"color", {{"mode", "albedo"}, {"grid", "Cd"}}}}, "no colour grid named \"Cd\""},
      {"velocity_grid", {{"velocity", {{"grid", "vel"}}}}, "no velocity grid named \"vel\""},
      {"majorant_scale", {{"majorant_scale", 1e-9}}, "/media/0/majorant_scale"},
  };
  for (const Fault& f : faults) {
    SCOPED_TRACE(f.name);
    json s = base;
    s["media"][0].update(f.medium_patch);
    const std::string scene = write_scene(dir, std::string(f.name) + ".json", s);
    Proc i = run({"info", scene});
    expect_error_exit(i);
    EXPECT_THAT(i.out, HasSubstr(f.message)) << i.out;
    EXPECT_THAT(i.out, HasSubstr("world bbox")) << "the report comes before the error: " << i.out;
    Proc r = run({"render", scene, "-q", "--spp", "1", "-o", dir + "/r.exr"});
    expect_error_exit(r);
    EXPECT_THAT(r.out, HasSubstr(f.message)) << r.out;
    Proc j = run({"info", "--json", scene});
    expect_error_exit(j);
    const json doc = info_json(j);
    ASSERT_TRUE(doc.is_array() && doc.size() == 1) << j.out;
    EXPECT_FALSE(doc[0]["renders"].get<bool>());
    EXPECT_THAT(doc[0]["error"].get<std::string>(), HasSubstr(f.message));
  }
  // twin: the scene without a fault, with a lens and a shutter
  json s = base;
  s["camera"]["aperture_radius"] = 0.5;
  s["camera"]["focus_distance"] = 30.0;
  s["camera"]["shutter"] = {-0.25, 0.25};
  const std::string scene = write_scene(dir, "fine.json", s);
  Proc t = run({"info", scene});
  ASSERT_TRUE(t.exited && t.code == 0) << t.describe();
  EXPECT_THAT(t.out, HasSubstr("thin lens      aperture radius 0.5, focus at 30")) << t.out;
  EXPECT_THAT(t.out, HasSubstr("shutter        -0.25 .. 0.25 s")) << t.out;
  Proc j = run({"info", "--json", scene});
  ASSERT_TRUE(j.exited && j.code == 0) << j.describe();
  const json doc = info_json(j);
  EXPECT_TRUE(doc[0]["renders"].get<bool>());
  EXPECT_EQ(doc[0]["camera"]["shutter"], json::array({-0.25, 0.25}));
  EXPECT_EQ(doc[0]["camera"]["aperture_radius"].get<double>(), 0.5);
}

// Settings of the scene alone that do not go together are the scene's errors: exit 1, its file and
// field named, by render and by info alike; the same asked for on the command line is a usage error
// (exit 2). The twin: each scene renders once the fault is taken out.
TEST(CliInfo, SettingsOfTheSceneThatDoNotGoTogetherAreItsErrors) {
  const std::string dir = test_dir();
  json base = vdb_scene(kShared + "/smoke1.vdb");
  base["film"]["width"] = 8;
  base["film"]["height"] = 8;
  base["film"]["spp"] = 2;
  struct Case {
    const char* name;
    std::function<void(json&)> fault, twin;
    const char* field;
    std::vector<std::string> flags;  // the same fault from the command line
  };
  const Case cases[] = {
      {"png_layers", [](json& s) { s["film"]["output"] = "x.png", s["film"]["aovs"] = {"depth"}; },
       [](json& s) { s["film"]["output"] = "x.exr"; }, "/film/output", {"-o", "PNG", "--aov", "depth"}},
      {"adaptive", [](json& s) { s["render"]["adaptive"] = true; }, [](json& s) { s["render"]["noise_target"] = 0.5; },
       "/render/adaptive", {"--adaptive"}},
      {"guiding_one_sample", [](json& s) { s["render"]["guiding"] = "on", s["film"]["spp"] = 1; },
       [](json& s) { s["film"]["spp"] = 2; }, "/render/guiding", {"--guiding", "on", "--spp", "1"}},
      {"equiangular_guided", [](json& s) { s["render"]["guiding"] = "on", s["render"]["equiangular"] = "on"; },
       [](json& s) { s["render"]["equiangular"] = "off"; }, "/render/equiangular", {"--guiding", "on", "--equiangular", "on"}},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    json s = base;
    c.fault(s);
    const std::string scene = write_scene(dir, std::string(c.name) + ".json", s);
    for (const std::vector<std::string>& cmd : {std::vector<std::string>{"info", scene}, std::vector<std::string>{"render", scene, "-q"}}) {
      Proc p = run(cmd);
      expect_error_exit(p);
      EXPECT_THAT(p.out, HasSubstr(std::string(c.name) + ".json: " + c.field + ": ")) << p.out;
    }
    std::vector<std::string> flagged = {"render", write_scene(dir, std::string(c.name) + "_plain.json", base), "-q", "-o", dir + "/f.exr"};
    for (const std::string& f : c.flags) flagged.push_back(f == "PNG" ? dir + "/f.png" : f);
    expect_error_exit(run(flagged), 2);
    c.twin(s);
    const std::string fixed = write_scene(dir, std::string(c.name) + "_twin.json", s);
    Proc t = run({"info", fixed});
    EXPECT_TRUE(t.exited && t.code == 0) << t.describe();
  }
}

}  // namespace
