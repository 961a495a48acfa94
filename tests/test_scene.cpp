// test_scene.cpp: the scene loader against the docs/scene-format.md contract.
//
// Design: most tests start from the full example of docs/scene-format.md (as nlohmann::json), change
// one thing and check either the parsed value or the error. An error must start with the scene
// name and the JSON path of the offending field, and carry a reason keyword, so each check pins
// down where the loader looked, not just that it threw. Files named by scenes are empty dummies in
// a per-test temporary folder: the loader only checks that they exist.
#include <chrono>
#include <unistd.h>

#include <algorithm>
#include <fstream>
#include <filesystem>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "image/image.h"
#include "scene/radiance.h"
#include "scene/scene.h"
#include "util/files.h"
#include "volume/volume.h"
#include "test_util.h"

#include <sys/stat.h>

namespace spectrack {
namespace {

using json = nlohmann::json;
using testing::AllOf;
using testing::HasSubstr;
using testing::Not;
using testing::StartsWith;
namespace fs = std::filesystem;

const char* kExample = R"({
  "format": "spectrack-scene/1",
  "camera": {
    "type": "perspective",
    "position": [0, 0, -4], "look_at": [0, 0, 0], "up": [0, 1, 0],
    "fov_deg": 40
  },
  "film": { "width": 512, "height": 512, "spp": 64, "output": "cloud.exr" },
  "render": {
    "tracker": "spectral-decomposition",
    "spectral_scheme": "history-average",
    "max_depth": -1,
    "seed": 0
  },
  "lights": [
    { "type": "environment", "radiance": [0.3, 0.4, 0.6] },
    { "type": "directional", "to_light": [-1, 1, -0.5], "irradiance": [4, 4, 4], "angle_deg": 0.53 }
  ],
  "media": [
    {
      "name": "cloud", "type": "vdb", "file": "cloud.vdb", "grid": "density",
      "density_scale": 1.0,
      "sigma_s": [1.0, 1.0, 1.0], "sigma_a": [0.05, 0.05, 0.05],
      "phase": { "type": "hg", "g": 0.6 },
      "emission": { "grid": "temperature", "radiance": [1.0, 0.45, 0.1], "scale": 1.0 },
      "transform": { "scale": 1.0, "rotate_deg": [0, 0, 0], "translate": [0, 0, 0] }
    },
    {
      "name": "haze", "type": "homogeneous", "bounds": [[-2, -2, -2], [2, 2, 2]],
      "sigma_s": [0.02, 0.02, 0.02], "sigma_a": [0.0, 0.0, 0.0],
      "phase": { "type": "isotropic" }
    }
  ]
})";

void touch(const fs::path& p) {
  fs::create_directories(p.parent_path());
  std::ofstream(p).put('\n');
}

class SceneTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() / ("spectrack_scene_test_" + std::to_string(getpid())) / info->name();
    fs::create_directories(dir_);
    touch(dir_ / "cloud.vdb");
    touch(dir_ / "sky.exr");
  }
  void TearDown() override { fs::remove_all(dir_.parent_path()); }

  static json example() { return json::parse(kExample); }
  static json minimal() { return json{{"format", "spectrack-scene/1"}}; }
  static json haze() {
    return json{{"type", "homogeneous"}, {"bounds", {{-1, -1, -1}, {1, 1, 1}}}};
  }
  SceneDesc parse(const json& j) const { return parse_scene(j.dump(2), "cloud.json", dir_.string()); }
  // Writes bytes to dir_/name and reads it as an image: the error message, or "accepted".
  std::string image_error(const std::string& name, const std::string& bytes) const {
    const std::string p = (dir_ / name).string();
    std::ofstream(p, std::ios::binary) << bytes;
    try {
      read_image(p);
    } catch (const Error& e) {
      return e.what();
    }
    return "accepted";
  }
  // The message of the expected error, or "" after recording a failure.
  std::string error_text(const std::string& text) const {
    try {
      parse_scene(text, "cloud.json", dir_.string());
    } catch (const Error& e) {
      return e.what();
    }
    ADD_FAILURE() << "no error for:\n" << text;
    return "";
  }
  std::string error(const json& j) const { return error_text(j.dump(2)); }
  // The error starts with "cloud.json: <path>: " and contains `reason`.
  void expect_error(const json& j, const std::string& path, const std::string& reason) const {
    std::string e = error(j);
    EXPECT_THAT(e, StartsWith("cloud.json: " + path + ": "));
    EXPECT_THAT(e, HasSubstr(reason));
  }
  std::string in_dir(const std::string& rel) const { return (dir_ / rel).lexically_normal().string(); }

  fs::path dir_;
};

#define EXPECT_SCENE_ERROR(j, path, reason) \
  do {                                      \
    SCOPED_TRACE(path);                     \
    expect_error(j, path, reason);          \
  } while (0)

// ---- name tables ----

TEST(SceneNames, TrackerNamesMatchEnumValues) {
  EXPECT_STREQ(tracker_name(ST_TRACKER_DELTA_PER_CHANNEL), "delta-per-channel");
  EXPECT_STREQ(tracker_name(ST_TRACKER_DELTA), "delta");
  EXPECT_STREQ(tracker_name(ST_TRACKER_SPECTRAL), "spectral");
  EXPECT_STREQ(tracker_name(ST_TRACKER_DECOMPOSITION), "decomposition");
  EXPECT_STREQ(tracker_name(ST_TRACKER_SPECTRAL_DECOMPOSITION), "spectral-decomposition");
}

TEST(SceneNames, SchemeNamesMatchEnumValues) {
  EXPECT_STREQ(scheme_name(ST_SCHEME_MAX), "max");
  EXPECT_STREQ(scheme_name(ST_SCHEME_AVERAGE), "average");
  EXPECT_STREQ(scheme_name(ST_SCHEME_HISTORY_MAX), "history-max");
  EXPECT_STREQ(scheme_name(ST_SCHEME_HISTORY_AVERAGE), "history-average");
}

TEST(SceneNames, RoundTrip) {
  for (int i = 0; i < ST_TRACKER_COUNT; ++i) EXPECT_EQ(tracker_from_name(tracker_name(i)), i);
  for (int i = 0; i < ST_SCHEME_COUNT; ++i) EXPECT_EQ(scheme_from_name(scheme_name(i)), i);
}

TEST(SceneNames, UnknownNamesAndValues) {
  EXPECT_EQ(tracker_from_name("ratio"), -1);
  EXPECT_EQ(tracker_from_name(""), -1);
  EXPECT_EQ(tracker_from_name("Delta"), -1);
  EXPECT_EQ(scheme_from_name("min"), -1);
  EXPECT_STREQ(tracker_name(-1), "unknown");
  EXPECT_STREQ(tracker_name(ST_TRACKER_COUNT), "unknown");
  EXPECT_STREQ(scheme_name(ST_SCHEME_COUNT), "unknown");
}

TEST(SceneNames, Lists) {
  EXPECT_EQ(tracker_names(), "delta-per-channel, delta, spectral, decomposition, spectral-decomposition, spectral-mis");
  EXPECT_EQ(scheme_names(), "max, average, history-max, history-average");
}

// ---- valid scenes ----

TEST_F(SceneTest, FullExampleParses) {
  SceneDesc s = parse(example());
  EXPECT_EQ(s.path, "cloud.json");
  EXPECT_EQ(s.dir, dir_.string());

  EXPECT_EQ(s.camera.type, ST_CAMERA_PERSPECTIVE);
  EXPECT_EQ(s.camera.position, (Vec3{0, 0, -4}));
  EXPECT_EQ(s.camera.look_at, (Vec3{0, 0, 0}));
  EXPECT_EQ(s.camera.up, (Vec3{0, 1, 0}));
  EXPECT_DOUBLE_EQ(s.camera.fov_deg, 40);

  EXPECT_EQ(s.film.width, 512);
  EXPECT_EQ(s.film.height, 512);
  EXPECT_EQ(s.film.spp, 64);
  EXPECT_EQ(s.film.output, in_dir("cloud.exr"));

  EXPECT_EQ(s.render.tracker, ST_TRACKER_SPECTRAL_DECOMPOSITION);
  EXPECT_EQ(s.render.scheme, ST_SCHEME_HISTORY_AVERAGE);
  EXPECT_FALSE(s.render.max_depth.has_value());
  EXPECT_EQ(s.render.seed, 0u);

  ASSERT_EQ(s.lights.size(), 2u);
  EXPECT_EQ(s.lights[0].type, ST_LIGHT_ENV_UNIFORM);
  EXPECT_EQ(s.lights[0].json_path, "/lights/0");
  EXPECT_EQ(s.lights[0].radiance, (Vec3{0.3, 0.4, 0.6}));
  EXPECT_TRUE(s.lights[0].map.empty());
  EXPECT_EQ(s.lights[1].type, ST_LIGHT_DIRECTIONAL);
  EXPECT_EQ(s.lights[1].json_path, "/lights/1");
  EXPECT_EQ(s.lights[1].to_light, (Vec3{-1, 1, -0.5}));
  EXPECT_EQ(s.lights[1].irradiance, (Vec3{4, 4, 4}));
  EXPECT_DOUBLE_EQ(s.lights[1].angle_deg, 0.53);

  ASSERT_EQ(s.media.size(), 2u);
  const MediumDesc& c = s.media[0];
  EXPECT_EQ(c.name, "cloud");
  EXPECT_EQ(c.json_path, "/media/0");
  EXPECT_EQ(c.type, ST_MEDIUM_VDB);
  EXPECT_EQ(c.file, in_dir("cloud.vdb"));
  EXPECT_EQ(c.grid, "density");
  EXPECT_EQ(c.grid_index, -1);
  EXPECT_DOUBLE_EQ(c.density_scale, 1.0);
  EXPECT_EQ(c.sigma_s, (Vec3{1, 1, 1}));
  EXPECT_EQ(c.sigma_a, (Vec3{0.05, 0.05, 0.05}));
  EXPECT_EQ(c.phase.type, ST_PHASE_HG);
  EXPECT_DOUBLE_EQ(c.phase.g, 0.6);
  EXPECT_TRUE(c.emission.present);
  EXPECT_EQ(c.emission.grid, "temperature");
  EXPECT_EQ(c.emission.radiance, (Vec3{1.0, 0.45, 0.1}));
  EXPECT_DOUBLE_EQ(c.emission.scale, 1.0);
  EXPECT_EQ(c.transform.scale, (Vec3{1, 1, 1}));
  EXPECT_EQ(c.transform.rotate_deg, (Vec3{0, 0, 0}));
  EXPECT_EQ(c.transform.translate, (Vec3{0, 0, 0}));
  EXPECT_DOUBLE_EQ(c.majorant_scale, 1.0);
  EXPECT_DOUBLE_EQ(c.minorant_scale, 1.0);

  const MediumDesc& h = s.media[1];
  EXPECT_EQ(h.name, "haze");
  EXPECT_EQ(h.json_path, "/media/1");
  EXPECT_EQ(h.type, ST_MEDIUM_HOMOGENEOUS);
  EXPECT_TRUE(h.file.empty());
  EXPECT_EQ(h.bounds[0], (Vec3{-2, -2, -2}));
  EXPECT_EQ(h.bounds[1], (Vec3{2, 2, 2}));
  EXPECT_EQ(h.sigma_s, (Vec3{0.02, 0.02, 0.02}));
  EXPECT_EQ(h.sigma_a, (Vec3{0, 0, 0}));
  EXPECT_EQ(h.phase.type, ST_PHASE_ISOTROPIC);
  EXPECT_FALSE(h.emission.present);
}

TEST_F(SceneTest, MinimalSceneGetsDefaults) {
  SceneDesc s = parse(minimal());
  EXPECT_EQ(s.camera.type, ST_CAMERA_PERSPECTIVE);
  EXPECT_EQ(s.camera.position, (Vec3{0, 0, -4}));
  EXPECT_DOUBLE_EQ(s.camera.fov_deg, 40);
  EXPECT_EQ(s.film.width, 512);
  EXPECT_EQ(s.film.height, 512);
  EXPECT_EQ(s.film.spp, 64);
  EXPECT_EQ(s.film.output, in_dir("out.exr"));
  EXPECT_EQ(s.render.tracker, ST_TRACKER_SPECTRAL_DECOMPOSITION);
  EXPECT_EQ(s.render.scheme, ST_SCHEME_HISTORY_AVERAGE);
  EXPECT_FALSE(s.render.max_depth.has_value());
  EXPECT_EQ(s.render.seed, 0u);
  EXPECT_TRUE(s.lights.empty());
  EXPECT_TRUE(s.media.empty());
}

TEST_F(SceneTest, EmptySectionsGetDefaults) {
  json j = minimal();
  j["camera"] = json::object();
  j["film"] = json::object();
  j["render"] = json::object();
  j["lights"] = json::array();
  j["media"] = json::array();
  SceneDesc s = parse(j);
  EXPECT_EQ(s.film.output, in_dir("out.exr"));
  EXPECT_EQ(s.render.tracker, ST_TRACKER_SPECTRAL_DECOMPOSITION);
}

TEST_F(SceneTest, MediumDefaults) {
  json j = minimal();
  j["media"] = {haze(), {{"type", "vdb"}, {"file", "cloud.vdb"}}};
  SceneDesc s = parse(j);
  ASSERT_EQ(s.media.size(), 2u);
  const MediumDesc& h = s.media[0];
  EXPECT_EQ(h.name, "medium0");
  EXPECT_DOUBLE_EQ(h.density_scale, 1.0);
  EXPECT_EQ(h.sigma_s, (Vec3{1, 1, 1}));
  EXPECT_EQ(h.sigma_a, (Vec3{0, 0, 0}));
  EXPECT_EQ(h.phase.type, ST_PHASE_ISOTROPIC);
  EXPECT_FALSE(h.emission.present);
  EXPECT_DOUBLE_EQ(h.majorant_scale, 1.0);
  EXPECT_DOUBLE_EQ(h.minorant_scale, 1.0);
  const MediumDesc& v = s.media[1];
  EXPECT_EQ(v.name, "medium1");
  EXPECT_EQ(v.grid, "density");
  EXPECT_EQ(v.grid_index, -1);
  EXPECT_EQ(v.transform.scale, (Vec3{1, 1, 1}));
}

TEST_F(SceneTest, LightDefaults) {
  json j = minimal();
  j["lights"] = {{{"type", "environment"}}, {{"type", "directional"}, {"to_light", {0, 0, 1}}}};
  SceneDesc s = parse(j);
  EXPECT_EQ(s.lights[0].type, ST_LIGHT_ENV_UNIFORM);
  EXPECT_EQ(s.lights[0].radiance, (Vec3{1, 1, 1}));
  EXPECT_EQ(s.lights[1].irradiance, (Vec3{1, 1, 1}));
  EXPECT_DOUBLE_EQ(s.lights[1].angle_deg, 0);
}

TEST_F(SceneTest, OptionalMediumFields) {
  json j = example();
  j["media"][0]["grid_index"] = 2;
  j["media"][0]["majorant_scale"] = 0.5;
  j["media"][0]["minorant_scale"] = 0;
  j["media"][0]["density_scale"] = 3.5;
  j["media"][1]["minorant_scale"] = 2;
  j["media"][1]["emission"] = {{"radiance", {1, 2, 3}}, {"scale", 0.5}};
  // the absorption model emits sigma_a times the colour: the haze's sigma_a of 0 would emit
  // nothing, which is refused naming the field; the twins: a colour of 0, and sigma_a > 0
  const std::string dark = st_test::error_of([&] { parse(j); });
  EXPECT_NE(dark.find("/media/1/emission: the absorption model"), std::string::npos) << dark;
  json black = j;
  black["media"][1]["emission"]["radiance"] = {0, 0, 0};
  EXPECT_NO_THROW(parse(black));
  j["media"][1]["sigma_a"] = {0.01, 0.01, 0.01};
  SceneDesc s = parse(j);
  EXPECT_EQ(s.media[0].grid_index, 2);
  EXPECT_DOUBLE_EQ(s.media[0].majorant_scale, 0.5);
  EXPECT_DOUBLE_EQ(s.media[0].minorant_scale, 0);
  EXPECT_DOUBLE_EQ(s.media[0].density_scale, 3.5);
  EXPECT_DOUBLE_EQ(s.media[1].minorant_scale, 2);
  EXPECT_TRUE(s.media[1].emission.present);
  EXPECT_TRUE(s.media[1].emission.grid.empty());
  EXPECT_EQ(s.media[1].emission.radiance, (Vec3{1, 2, 3}));
  EXPECT_DOUBLE_EQ(s.media[1].emission.scale, 0.5);
}

TEST_F(SceneTest, TransformScaleNumberOrTriple) {
  json j = example();
  j["media"][0]["transform"] = {{"scale", 2.5}, {"rotate_deg", {10, 20, 30}}, {"translate", {1, -2, 3}}};
  SceneDesc s = parse(j);
  EXPECT_EQ(s.media[0].transform.scale, (Vec3{2.5, 2.5, 2.5}));
  EXPECT_EQ(s.media[0].transform.rotate_deg, (Vec3{10, 20, 30}));
  EXPECT_EQ(s.media[0].transform.translate, (Vec3{1, -2, 3}));
  j["media"][0]["transform"] = {{"scale", {1, -2, 0.5}}};
  EXPECT_EQ(parse(j).media[0].transform.scale, (Vec3{1, -2, 0.5}));
}

TEST_F(SceneTest, OrthographicCamera) {
  json j = minimal();
  j["camera"] = {{"type", "orthographic"}, {"height", 3.5}, {"position", {1, 2, 3}}, {"look_at", {1, 2, 0}},
                 {"up", {1, 0, 0}}};
  SceneDesc s = parse(j);
  EXPECT_EQ(s.camera.type, ST_CAMERA_ORTHOGRAPHIC);
  EXPECT_DOUBLE_EQ(s.camera.height, 3.5);
  EXPECT_EQ(s.camera.position, (Vec3{1, 2, 3}));
  EXPECT_EQ(s.camera.up, (Vec3{1, 0, 0}));
}

TEST_F(SceneTest, EnvironmentMap) {
  json j = example();
  j["lights"][0] = {{"type", "environment"}, {"map", "sky.exr"}, {"scale", 2}};
  SceneDesc s = parse(j);
  EXPECT_EQ(s.lights[0].type, ST_LIGHT_ENV_MAP);
  EXPECT_EQ(s.lights[0].map, in_dir("sky.exr"));
  EXPECT_DOUBLE_EQ(s.lights[0].scale, 2);
  j["lights"][0].erase("scale");
  EXPECT_DOUBLE_EQ(parse(j).lights[0].scale, 1);
}

TEST_F(SceneTest, RenderSettings) {
  json j = example();
  j["render"] = {{"tracker", "delta-per-channel"}, {"spectral_scheme", "max"}, {"max_depth", 12},
                 {"seed", 4294967295ull}};
  SceneDesc s = parse(j);
  EXPECT_EQ(s.render.tracker, ST_TRACKER_DELTA_PER_CHANNEL);
  EXPECT_EQ(s.render.scheme, ST_SCHEME_MAX);
  EXPECT_EQ(s.render.max_depth, 12);
  EXPECT_EQ(s.render.seed, 4294967295u);
}

TEST_F(SceneTest, IntegersMayBeWrittenAsIntegralFloats) {
  json j = example();
  j["film"]["width"] = 640.0;
  j["film"]["spp"] = 1e3;
  SceneDesc s = parse(j);
  EXPECT_EQ(s.film.width, 640);
  EXPECT_EQ(s.film.spp, 1000);
}

TEST_F(SceneTest, LimitsAreInclusive) {
  json j = example();
  j["film"] = {{"width", 65536}, {"height", 4096}, {"spp", 1 << 24}};
  j["media"][0]["phase"]["g"] = -0.999;
  j["lights"][1]["angle_deg"] = 0;
  j["camera"]["fov_deg"] = 179.9;
  SceneDesc s = parse(j);
  EXPECT_EQ(s.film.width * s.film.height, 1 << 28);
  EXPECT_EQ(s.film.spp, 1 << 24);
}

TEST_F(SceneTest, MaxMediaAndLightsAccepted) {
  json j = minimal();
  for (int i = 0; i < ST_MAX_MEDIA; ++i) j["media"].push_back(haze());
  j["lights"].push_back({{"type", "environment"}});
  for (int i = 1; i < ST_MAX_LIGHTS; ++i) j["lights"].push_back({{"type", "directional"}, {"to_light", {0, 1, 0}}});
  SceneDesc s = parse(j);
  EXPECT_EQ(s.media.size(), size_t(ST_MAX_MEDIA));
  EXPECT_EQ(s.lights.size(), size_t(ST_MAX_LIGHTS));
  EXPECT_EQ(s.media[7].name, "medium7");
}

// ---- paths ----

TEST_F(SceneTest, RelativePathsResolveAgainstDir) {
  touch(dir_ / "volumes" / "smoke.nvdb");
  touch(dir_ / "maps" / "sky.hdr");
  json j = example();
  j["media"][0]["file"] = "volumes/./smoke.nvdb";
  j["lights"][0] = {{"type", "environment"}, {"map", "maps/../maps/sky.hdr"}};
  j["film"]["output"] = "renders/frame.png";
  SceneDesc s = parse(j);
  EXPECT_EQ(s.media[0].file, in_dir("volumes/smoke.nvdb"));
  EXPECT_EQ(s.lights[0].map, in_dir("maps/sky.hdr"));
  EXPECT_EQ(s.film.output, in_dir("renders/frame.png"));
  EXPECT_TRUE(fs::path(s.media[0].file).is_absolute());
}

TEST_F(SceneTest, AbsolutePathsAreKept) {
  json j = example();
  j["media"][0]["file"] = (dir_ / "cloud.vdb").string();
  j["film"]["output"] = "/tmp/elsewhere/x.exr";
  SceneDesc s = parse(j);
  EXPECT_EQ(s.media[0].file, (dir_ / "cloud.vdb").string());
  EXPECT_EQ(s.film.output, "/tmp/elsewhere/x.exr");
}

TEST_F(SceneTest, LoadSceneResolvesAgainstTheScenesFolder) {
  touch(dir_ / "volumes" / "cloud.vdb");
  json j = example();
  j["media"][0]["file"] = "../volumes/cloud.vdb";
  fs::create_directories(dir_ / "scenes");
  std::string path = (dir_ / "scenes" / "cloud.json").string();
  std::ofstream(path) << j.dump(2);
  SceneDesc s = load_scene(path);
  EXPECT_EQ(s.path, path);
  EXPECT_EQ(s.dir, (dir_ / "scenes").string());
  EXPECT_EQ(s.media[0].file, in_dir("volumes/cloud.vdb"));
  EXPECT_EQ(s.film.output, in_dir("scenes/cloud.exr"));
}

TEST_F(SceneTest, LoadSceneErrorsNameTheFileAsGiven) {
  std::string path = (dir_ / "bad.json").string();
  std::ofstream(path) << R"({"format": "spectrack-scene/1", "films": {}})";
  try {
    load_scene(path);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), StartsWith(path + ": /films: unknown field"));
  }
}

TEST_F(SceneTest, LoadSceneMissingFile) {
  std::string path = (dir_ / "nope.json").string();
  try {
    load_scene(path);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), path + ": cannot open scene file (No such file or directory)");
  }
}

TEST_F(SceneTest, LoadSceneOnADirectory) {
  try {
    load_scene(dir_.string());
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), StartsWith(dir_.string() + ": cannot open scene file ("));
  }
}

TEST_F(SceneTest, MissingVdbFileNamesTheResolvedPath) {
  json j = example();
  j["media"][0]["file"] = "missing/cloud.vdb";
  EXPECT_SCENE_ERROR(j, "/media/0/file", in_dir("missing/cloud.vdb") + ": no such file");
}

TEST_F(SceneTest, VdbFileThatIsADirectory) {
  fs::create_directories(dir_ / "adir");
  json j = example();
  j["media"][0]["file"] = "adir";
  EXPECT_SCENE_ERROR(j, "/media/0/file", "is a directory");
}

TEST_F(SceneTest, MissingEnvironmentMap) {
  json j = example();
  j["lights"][0] = {{"type", "environment"}, {"map", "nosky.exr"}};
  EXPECT_SCENE_ERROR(j, "/lights/0/map", in_dir("nosky.exr") + ": no such file");
}

// ---- format and syntax ----

TEST_F(SceneTest, FormatIsRequired) {
  json j = example();
  j.erase("format");
  EXPECT_SCENE_ERROR(j, "/format", "missing required field");
}

TEST_F(SceneTest, FormatMustMatch) {
  json j = example();
  j["format"] = "spectrack-scene/2";
  EXPECT_SCENE_ERROR(j, "/format", "unsupported format \"spectrack-scene/2\"");
  j["format"] = 1;
  EXPECT_SCENE_ERROR(j, "/format", "expected a string");
}

TEST_F(SceneTest, RootMustBeAnObject) {
  EXPECT_SCENE_ERROR(json::array(), "/", "expected an object");
}

TEST_F(SceneTest, SyntaxErrorHasLineAndColumn) {
  std::string e = error_text("{\n  \"format\": \"spectrack-scene/1\",\n  \"film\": { \"width\": tru }\n}");
  EXPECT_THAT(e, StartsWith("cloud.json: "));
  EXPECT_THAT(e, HasSubstr("line 3"));
  EXPECT_THAT(e, HasSubstr("column"));
  EXPECT_THAT(e, HasSubstr("syntax error"));
}

TEST_F(SceneTest, EmptyTextIsASyntaxError) {
  EXPECT_THAT(error_text(""), StartsWith("cloud.json: parse error at line 1, column 1"));
}

TEST_F(SceneTest, TrailingGarbageIsASyntaxError) {
  EXPECT_THAT(error_text("{\"format\": \"spectrack-scene/1\"} x"), HasSubstr("syntax error"));
}

TEST_F(SceneTest, NumberOverflowIsRejected) {
  std::string text = example().dump(2);
  text.replace(text.find("\"density_scale\": 1.0"), 20, "\"density_scale\": 1e999");
  std::string e = error_text(text);
  size_t at = text.find("1e999");
  size_t line = 1 + std::count(text.begin(), text.begin() + at, '\n');
  EXPECT_THAT(e, StartsWith("cloud.json: line " + std::to_string(line) + ", column "));
  EXPECT_THAT(e, HasSubstr("1e999"));
  EXPECT_THAT(e, HasSubstr("finite"));
}

TEST_F(SceneTest, DuplicateKeyIsAnError) {
  std::string text = example().dump(2);
  text.replace(text.find("\"name\": \"haze\""), 14, "\"name\": \"haze\", \"name\": \"fog\"");
  EXPECT_THAT(error_text(text), StartsWith("cloud.json: /media/1/name: duplicate field"));
  EXPECT_THAT(error_text(R"({"format": "spectrack-scene/1", "format": "spectrack-scene/1"})"),
              StartsWith("cloud.json: /format: duplicate field"));
}

// ---- unknown fields at every depth ----

TEST_F(SceneTest, UnknownFieldAtRoot) {
  json j = example();
  j["lighs"] = json::array();
  EXPECT_SCENE_ERROR(j, "/lighs", "unknown field (expected one of: format, camera, film, render, lights, media, ground)");
}

TEST_F(SceneTest, UnknownFieldInSections) {
  json j = example();
  j["camera"]["fov"] = 30;
  EXPECT_SCENE_ERROR(j, "/camera/fov", "unknown field");
  j = example();
  j["film"]["samples"] = 30;
  EXPECT_SCENE_ERROR(j, "/film/samples", "unknown field");
  j = example();
  j["render"]["scheme"] = "max";
  EXPECT_SCENE_ERROR(j, "/render/scheme", "unknown field (expected one of: tracker, spectral_scheme, absorption, light_sampling, transmittance, lookup, color, max_depth, seed, time_limit, guiding, noise_target, adaptive, equiangular, wavelength_sampling)");
}

TEST_F(SceneTest, UnknownFieldInArrays) {
  json j = example();
  j["lights"][1]["irradience"] = {1, 1, 1};
  EXPECT_SCENE_ERROR(j, "/lights/1/irradience", "unknown field");
  j = example();
  j["media"][0]["sigma_x"] = 1;
  EXPECT_SCENE_ERROR(j, "/media/0/sigma_x", "unknown field (expected one of: name, type, ");
}

TEST_F(SceneTest, UnknownFieldInNestedObjects) {
  json j = example();
  j["media"][0]["phase"]["gg"] = 0.1;
  EXPECT_SCENE_ERROR(j, "/media/0/phase/gg", "unknown field");
  j = example();
  j["media"][0]["emission"]["color"] = {1, 1, 1};
  EXPECT_SCENE_ERROR(j, "/media/0/emission/color", "unknown field");
  j = example();
  j["media"][0]["transform"]["rotate"] = {0, 0, 0};
  EXPECT_SCENE_ERROR(j, "/media/0/transform/rotate", "unknown field");
}

TEST_F(SceneTest, UnknownFieldIsReportedBeforeAMissingType) {
  json j = example();
  j["media"][1].erase("type");
  j["media"][1]["typ"] = "homogeneous";
  EXPECT_SCENE_ERROR(j, "/media/1/typ", "unknown field");
}

TEST_F(SceneTest, UnknownFieldWithSlashIsEscapedInThePath) {
  json j = example();
  j["camera"]["a/b"] = 1;
  EXPECT_SCENE_ERROR(j, "/camera/a~1b", "unknown field");
}

TEST_F(SceneTest, FieldsOfAnotherType) {
  json j = example();
  j["camera"]["height"] = 2;
  EXPECT_SCENE_ERROR(j, "/camera/height", "not allowed for a perspective camera");
  j = example();
  j["camera"]["type"] = "orthographic";
  EXPECT_SCENE_ERROR(j, "/camera/fov_deg", "not allowed for an orthographic camera");
  j = example();
  j["media"][1]["file"] = "cloud.vdb";
  EXPECT_SCENE_ERROR(j, "/media/1/file", "not allowed for a homogeneous medium");
  j = example();
  j["media"][1]["grid"] = "density";
  EXPECT_SCENE_ERROR(j, "/media/1/grid", "not allowed for a homogeneous medium");
  j = example();
  j["media"][1]["transform"] = {{"scale", 2}};
  EXPECT_SCENE_ERROR(j, "/media/1/transform", "not allowed for a homogeneous medium");
  j = example();
  j["media"][0]["bounds"] = {{0, 0, 0}, {1, 1, 1}};
  EXPECT_SCENE_ERROR(j, "/media/0/bounds", "not allowed for a vdb medium");
  j = example();
  j["media"][1]["emission"] = {{"grid", "temperature"}, {"radiance", {1, 1, 1}}};
  EXPECT_SCENE_ERROR(j, "/media/1/emission/grid", "not allowed for a homogeneous medium's emission");
  j = example();
  j["media"][1]["phase"]["g"] = 0.3;
  EXPECT_SCENE_ERROR(j, "/media/1/phase/g", "not allowed for an isotropic phase function");
  j = example();
  j["lights"][0]["to_light"] = {0, 1, 0};
  EXPECT_SCENE_ERROR(j, "/lights/0/to_light", "not allowed for an environment light");
  j = example();
  j["lights"][1]["radiance"] = {1, 1, 1};
  EXPECT_SCENE_ERROR(j, "/lights/1/radiance", "not allowed for a directional light");
}

// ---- wrong JSON types ----

TEST_F(SceneTest, WrongTypes) {
  json j = example();
  j["film"]["width"] = "512";
  EXPECT_SCENE_ERROR(j, "/film/width", "expected an integer, got string");
  j = example();
  j["film"]["spp"] = 1.5;
  EXPECT_SCENE_ERROR(j, "/film/spp", "expected an integer");
  j = example();
  j["camera"]["fov_deg"] = true;
  EXPECT_SCENE_ERROR(j, "/camera/fov_deg", "expected a number, got boolean");
  j = example();
  j["camera"] = json::array();
  EXPECT_SCENE_ERROR(j, "/camera", "expected an object, got array");
  j = example();
  j["lights"] = json::object();
  EXPECT_SCENE_ERROR(j, "/lights", "expected an array, got object");
  j = example();
  j["media"][1] = "haze";
  EXPECT_SCENE_ERROR(j, "/media/1", "expected an object, got string");
  j = example();
  j["media"][0]["name"] = 3;
  EXPECT_SCENE_ERROR(j, "/media/0/name", "expected a string, got number");
  j = example();
  j["render"]["tracker"] = nullptr;
  EXPECT_SCENE_ERROR(j, "/render/tracker", "expected a string, got null");
  j = example();
  j["media"][0]["phase"] = "hg";
  EXPECT_SCENE_ERROR(j, "/media/0/phase", "expected an object");
}

TEST_F(SceneTest, WrongVectorShapes) {
  json j = example();
  j["media"][0]["sigma_s"] = {1, 1};
  EXPECT_SCENE_ERROR(j, "/media/0/sigma_s", "expected an array of 3 numbers, got an array of 2 values");
  j = example();
  j["media"][0]["sigma_a"] = {1, "1", 1};
  EXPECT_SCENE_ERROR(j, "/media/0/sigma_a", "expected an array of 3 numbers");
  j = example();
  j["camera"]["position"] = 4;
  EXPECT_SCENE_ERROR(j, "/camera/position", "expected an array of 3 numbers, got number");
  j = example();
  j["media"][1]["bounds"] = {{0, 0, 0}};
  EXPECT_SCENE_ERROR(j, "/media/1/bounds", "expected [[xmin");
  j = example();
  j["media"][1]["bounds"] = {{0, 0, 0}, {1, 1}};
  EXPECT_SCENE_ERROR(j, "/media/1/bounds/1", "expected an array of 3 numbers");
  j = example();
  j["media"][0]["transform"]["scale"] = "big";
  EXPECT_SCENE_ERROR(j, "/media/0/transform/scale", "expected a number or an array of 3 numbers");
}

// ---- missing required fields ----

TEST_F(SceneTest, MissingRequiredFields) {
  json j = example();
  j["media"][0].erase("type");
  EXPECT_SCENE_ERROR(j, "/media/0/type", "missing required field");
  j = example();
  j["media"][0].erase("file");
  EXPECT_SCENE_ERROR(j, "/media/0/file", "missing required field");
  j = example();
  j["media"][1].erase("bounds");
  EXPECT_SCENE_ERROR(j, "/media/1/bounds", "missing required field");
  j = example();
  j["lights"][0].erase("type");
  EXPECT_SCENE_ERROR(j, "/lights/0/type", "missing required field");
  j = example();
  j["lights"][1].erase("to_light");
  EXPECT_SCENE_ERROR(j, "/lights/1/to_light", "missing required field");
  j = example();
  j["media"][0]["phase"].erase("type");
  EXPECT_SCENE_ERROR(j, "/media/0/phase/type", "missing required field");
  j = example();
  j["media"][0]["phase"].erase("g");
  EXPECT_SCENE_ERROR(j, "/media/0/phase/g", "missing required field");
  j = example();
  j["media"][0]["emission"].erase("radiance");
  EXPECT_SCENE_ERROR(j, "/media/0/emission/radiance", "missing required field");
}

// The render fields an option overrides take the option's range (--noise-target, --time-limit).
TEST_F(SceneTest, RenderFieldsTakeTheirOptionsRange) {
  json j = example();
  j["render"]["noise_target"] = 1e-30;
  EXPECT_SCENE_ERROR(j, "/render/noise_target", "out of range (must be in [1e-06, 1])");
  j = example();
  j["render"]["time_limit"] = 1e-4;
  EXPECT_SCENE_ERROR(j, "/render/time_limit", "out of range (must be in [0.001, 1000000000])");
  j = example();
  j["render"]["noise_target"] = 0.02;  // the twin: values inside the range load
  j["render"]["time_limit"] = 60;
  EXPECT_NO_THROW(parse(j));
}

// ---- unknown enum names ----

TEST_F(SceneTest, UnknownTypeNames) {
  json j = example();
  j["render"]["tracker"] = "ratio";
  EXPECT_SCENE_ERROR(j, "/render/tracker", "unknown tracker \"ratio\" (expected one of: " + tracker_names() + ")");
  j = example();
  j["render"]["spectral_scheme"] = "min";
  EXPECT_SCENE_ERROR(j, "/render/spectral_scheme", "(expected one of: " + scheme_names() + ")");
  j = example();
  j["render"]["absorption"] = "russian";
  EXPECT_SCENE_ERROR(j, "/render/absorption", "unknown absorption mode \"russian\" (expected one of: event, weight)");
  j = example();
  j["render"]["absorption"] = 1;
  EXPECT_SCENE_ERROR(j, "/render/absorption", "");
  j = example();
  j["render"]["light_sampling"] = "random";
  EXPECT_SCENE_ERROR(j, "/render/light_sampling",
                     "unknown light sampling \"random\" (expected one of: all, uniform, power, contribution, auto)");
  j = example();
  j["render"]["light_sampling"] = "power";
  EXPECT_EQ(parse(j).render.light_sampling, ST_LIGHT_SAMPLING_POWER);
  j["render"]["light_sampling"] = "contribution";
  EXPECT_EQ(parse(j).render.light_sampling, ST_LIGHT_SAMPLING_CONTRIBUTION);
  EXPECT_FALSE(parse(example()).render.light_sampling.has_value()) << "not given: the default (settings.h)";
  j = example();
  j["render"]["lookup"] = "nearest";
  EXPECT_SCENE_ERROR(j, "/render/lookup",
                     "unknown density lookup mode \"nearest\" (expected one of: trilinear, stochastic)");
  j["render"]["lookup"] = "stochastic";
  EXPECT_EQ(parse(j).render.lookup, ST_LOOKUP_STOCHASTIC);
  EXPECT_FALSE(parse(example()).render.lookup.has_value()) << "not given: the default (settings.h)";
  j = example();
  j["camera"]["type"] = "fisheye";
  EXPECT_SCENE_ERROR(j, "/camera/type", "unknown camera type \"fisheye\"");
  j = example();
  j["lights"][1]["type"] = "area";
  EXPECT_SCENE_ERROR(j, "/lights/1/type", "unknown light type \"area\"");
  j = example();
  j["media"][0]["type"] = "grid";
  EXPECT_SCENE_ERROR(j, "/media/0/type", "unknown medium type \"grid\"");
  j = example();
  j["media"][0]["phase"]["type"] = "fournier-forand";  // rayleigh, draine, hg2 and mie are phases now
  EXPECT_SCENE_ERROR(j, "/media/0/phase/type", "unknown phase function \"fournier-forand\"");
}

// ---- ranges ----

TEST_F(SceneTest, FilmRanges) {
  json j = example();
  j["film"]["width"] = 0;
  EXPECT_SCENE_ERROR(j, "/film/width", "out of range");
  j["film"]["width"] = 65537;
  EXPECT_SCENE_ERROR(j, "/film/width", "out of range");
  j = example();
  j["film"]["height"] = -5;
  EXPECT_SCENE_ERROR(j, "/film/height", "value -5 is out of range");
  j = example();
  j["film"]["width"] = 65536;
  j["film"]["height"] = 4097;
  EXPECT_SCENE_ERROR(j, "/film", "too many");
  j = example();
  j["film"]["spp"] = 0;
  EXPECT_SCENE_ERROR(j, "/film/spp", "out of range");
  j["film"]["spp"] = (1 << 24) + 1;
  EXPECT_SCENE_ERROR(j, "/film/spp", "out of range");
  j = example();
  j["film"]["output"] = "cloud.jpg";
  EXPECT_SCENE_ERROR(j, "/film/output", "unsupported image type");
  j["film"]["output"] = "";
  EXPECT_SCENE_ERROR(j, "/film/output", "must not be empty");
}

TEST_F(SceneTest, RenderRanges) {
  json j = example();
  j["render"]["max_depth"] = -2;
  EXPECT_SCENE_ERROR(j, "/render/max_depth", "out of range");
  j = example();
  j["render"]["seed"] = -1;
  EXPECT_SCENE_ERROR(j, "/render/seed", "out of range");
  j["render"]["seed"] = 4294967296ull;
  EXPECT_SCENE_ERROR(j, "/render/seed", "out of range");
  j["render"]["seed"] = 18446744073709551615ull;
  EXPECT_SCENE_ERROR(j, "/render/seed", "out of range");
  j["render"]["seed"] = 1e30;
  EXPECT_SCENE_ERROR(j, "/render/seed", "out of range");
}

TEST_F(SceneTest, CameraRanges) {
  json j = example();
  j["camera"]["fov_deg"] = 0;
  EXPECT_SCENE_ERROR(j, "/camera/fov_deg", "out of range (must be in (0, 180))");
  j["camera"]["fov_deg"] = 180;
  EXPECT_SCENE_ERROR(j, "/camera/fov_deg", "out of range");
  j = example();
  j["camera"] = {{"type", "orthographic"}, {"height", 0}};
  EXPECT_SCENE_ERROR(j, "/camera/height", "out of range (must be > 0)");
}

TEST_F(SceneTest, CameraGeometry) {
  json j = example();
  j["camera"]["look_at"] = {0, 0, -4};
  EXPECT_SCENE_ERROR(j, "/camera/look_at", "equals the camera position");
  j = example();
  j["camera"]["up"] = {0, 0, 2};
  EXPECT_SCENE_ERROR(j, "/camera/up", "parallel to the view direction");
  j["camera"]["up"] = {0, 0, -1};
  EXPECT_SCENE_ERROR(j, "/camera/up", "parallel");
  j["camera"]["up"] = {0, 0, 0};
  EXPECT_SCENE_ERROR(j, "/camera/up", "zero");
  j["camera"]["up"] = {0, 1e-3, 1};
  EXPECT_NO_THROW(parse(j));
  // any length of up, and a view direction of any length (their squares once overflowed or vanished)
  for (double s : {1e-300, 1e155, 1e300}) {
    j = example();
    j["camera"]["up"] = {0, s, 0};
    EXPECT_NO_THROW(parse(j)) << s;
    j["camera"]["up"] = {0, 0, s};
    EXPECT_SCENE_ERROR(j, "/camera/up", "parallel to the view direction");
  }
  j = example();
  j["camera"]["position"] = {0, 0, 0};
  j["camera"]["look_at"] = {0, 0, 1e-300};
  EXPECT_NO_THROW(parse(j));
}

TEST_F(SceneTest, NegativeCoefficientsNameTheMediumAndField) {
  json j = example();
  j["media"][0]["sigma_s"] = {1, -1, 1};
  std::string e = error(j);
  EXPECT_THAT(e, StartsWith("cloud.json: /media/0/sigma_s: value -1 is negative"));
  EXPECT_THAT(e, HasSubstr("medium \"cloud\""));
  j = example();
  j["media"][1]["sigma_a"] = {0, 0, -0.5};
  e = error(j);
  EXPECT_THAT(e, StartsWith("cloud.json: /media/1/sigma_a: value -0.5 is negative"));
  EXPECT_THAT(e, HasSubstr("medium \"haze\""));
  j = example();
  j["media"][0]["density_scale"] = -2;
  EXPECT_SCENE_ERROR(j, "/media/0/density_scale", "negative");
  j = example();
  j["media"][0]["emission"]["radiance"] = {-1, 0, 0};
  EXPECT_SCENE_ERROR(j, "/media/0/emission/radiance", "negative");
  j = example();
  j["media"][0]["emission"]["scale"] = -1;
  EXPECT_SCENE_ERROR(j, "/media/0/emission/scale", "negative");
}

TEST_F(SceneTest, NegativeLightValues) {
  json j = example();
  j["lights"][0]["radiance"] = {0.3, -0.4, 0.6};
  EXPECT_SCENE_ERROR(j, "/lights/0/radiance", "value -0.4 is negative");
  j = example();
  j["lights"][1]["irradiance"] = {-4, 4, 4};
  EXPECT_SCENE_ERROR(j, "/lights/1/irradiance", "negative");
  j = example();
  j["lights"][0] = {{"type", "environment"}, {"map", "sky.exr"}, {"scale", -1}};
  EXPECT_SCENE_ERROR(j, "/lights/0/scale", "negative");
}

TEST_F(SceneTest, PhaseRange) {
  json j = example();
  j["media"][0]["phase"]["g"] = 1;
  EXPECT_SCENE_ERROR(j, "/media/0/phase/g", "out of range (must be in (-1, 1))");
  j["media"][0]["phase"]["g"] = -1;
  EXPECT_SCENE_ERROR(j, "/media/0/phase/g", "out of range");
}

TEST_F(SceneTest, DirectionalLightRanges) {
  json j = example();
  j["lights"][1]["angle_deg"] = 180;
  EXPECT_SCENE_ERROR(j, "/lights/1/angle_deg", "out of range (must be in [0, 180))");
  j["lights"][1]["angle_deg"] = -0.1;
  EXPECT_SCENE_ERROR(j, "/lights/1/angle_deg", "out of range");
  j = example();
  j["lights"][1]["to_light"] = {0, 0, 0};
  EXPECT_SCENE_ERROR(j, "/lights/1/to_light", "must not be zero");
}

TEST_F(SceneTest, HomogeneousBounds) {
  json j = example();
  j["media"][1]["bounds"] = {{-2, 2, -2}, {2, 2, 2}};
  EXPECT_SCENE_ERROR(j, "/media/1/bounds", "min >= max on the y axis");
  j["media"][1]["bounds"] = {{3, -2, -2}, {2, 2, 2}};
  EXPECT_SCENE_ERROR(j, "/media/1/bounds", "on the x axis");
}

TEST_F(SceneTest, MediumScalesAndGridIndex) {
  json j = example();
  j["media"][0]["majorant_scale"] = 0;
  EXPECT_SCENE_ERROR(j, "/media/0/majorant_scale", "out of range (must be > 0)");
  j = example();
  j["media"][0]["minorant_scale"] = -0.5;
  EXPECT_SCENE_ERROR(j, "/media/0/minorant_scale", "negative");
  j = example();
  j["media"][0]["grid_index"] = -1;
  EXPECT_SCENE_ERROR(j, "/media/0/grid_index", "out of range");
  j["media"][0]["grid_index"] = 0.5;
  EXPECT_SCENE_ERROR(j, "/media/0/grid_index", "expected an integer");
  j = example();
  j["media"][0]["grid"] = "";
  EXPECT_SCENE_ERROR(j, "/media/0/grid", "must not be empty");
}

TEST_F(SceneTest, TransformScaleMustBeNonZero) {
  json j = example();
  j["media"][0]["transform"]["scale"] = 0;
  EXPECT_SCENE_ERROR(j, "/media/0/transform/scale", "must not be zero");
  j["media"][0]["transform"]["scale"] = {1, 0, 1};
  EXPECT_SCENE_ERROR(j, "/media/0/transform/scale", "must not be zero");
}

// ---- counts and uniqueness ----

TEST_F(SceneTest, TooManyMedia) {
  json j = minimal();
  for (int i = 0; i <= ST_MAX_MEDIA; ++i) j["media"].push_back(haze());
  EXPECT_SCENE_ERROR(j, "/media", "at most " + std::to_string(ST_MAX_MEDIA));
}

TEST_F(SceneTest, TooManyLights) {
  json j = minimal();
  for (int i = 0; i <= ST_MAX_LIGHTS; ++i) j["lights"].push_back({{"type", "directional"}, {"to_light", {0, 1, 0}}});
  EXPECT_SCENE_ERROR(j, "/lights", "at most " + std::to_string(ST_MAX_LIGHTS));
}

TEST_F(SceneTest, DuplicateMediumNames) {
  json j = example();
  j["media"][1]["name"] = "cloud";
  EXPECT_SCENE_ERROR(j, "/media/1/name", "duplicate medium name \"cloud\" (also used by /media/0)");
  j = minimal();
  json named = haze();
  named["name"] = "medium0";
  j["media"] = {haze(), named};
  EXPECT_SCENE_ERROR(j, "/media/1/name", "duplicate medium name \"medium0\"");
  j = example();
  j["media"][1]["name"] = "";
  EXPECT_SCENE_ERROR(j, "/media/1/name", "must not be empty");
}

TEST_F(SceneTest, AtMostOneEnvironmentLight) {
  json j = example();
  j["lights"].push_back({{"type", "environment"}, {"map", "sky.exr"}});
  EXPECT_SCENE_ERROR(j, "/lights/2", "only one environment light is allowed (the first is /lights/0)");
}

TEST_F(SceneTest, EnvironmentRadianceAndMapAreExclusive) {
  json j = example();
  j["lights"][0]["map"] = "sky.exr";
  EXPECT_SCENE_ERROR(j, "/lights/0/radiance", "not allowed together with \"map\"");
  j = example();
  j["lights"][0]["scale"] = 2;
  EXPECT_SCENE_ERROR(j, "/lights/0/scale", "only allowed with \"map\"");
  j = example();
  j["lights"][0]["rotate_deg"] = 90;
  EXPECT_SCENE_ERROR(j, "/lights/0/rotate_deg", "only allowed with \"map\"");
  j = example();
  j["lights"][0].erase("radiance");
  j["lights"][0]["map"] = "sky.exr";
  j["lights"][0]["rotate_deg"] = 400;
  EXPECT_SCENE_ERROR(j, "/lights/0/rotate_deg", "in [-360, 360]");
  j["lights"][0]["rotate_deg"] = -135.5;
  EXPECT_EQ(parse(j).lights[0].rotate_deg, -135.5);
}

TEST_F(SceneTest, ErrorsInsideAMediumNameIt) {
  json j = example();
  j["media"][1]["phase"]["type"] = "hg";
  j["media"][1]["phase"]["g"] = 2;
  EXPECT_THAT(error(j), HasSubstr("in medium \"haze\""));
  j = example();
  j["film"]["spp"] = 0;
  EXPECT_THAT(error(j), testing::Not(HasSubstr("in medium")));
}

// ---- hostile inputs (docs/limits.md): magnitudes the float kernels cannot carry, files that are not
// files, images that would be misread, paths that collide ----

TEST_F(SceneTest, LightMagnitudesThatOverflowFloatAreRefused) {
  json j = example();
  j["lights"] = json::array({{{"type", "directional"}, {"to_light", {0, 1, 0}}, {"irradiance", {1e38, 1, 1}}}});
  EXPECT_SCENE_ERROR(j, "/lights/0/irradiance", "value 1e+38 is too large");
  j["lights"] = json::array({{{"type", "environment"}, {"radiance", {1, 3e38, 1}}}});
  EXPECT_SCENE_ERROR(j, "/lights/0/radiance", "value 3e+38 is too large");
  j["lights"] = json::array({{{"type", "environment"}, {"radiance", {1e19, 1, 1}}}});  // 4 pi x 1e19 > 1e20
  EXPECT_SCENE_ERROR(j, "/lights/0/radiance", "too large");
  // an environment map's scale is bounded through scale x its largest texel (once the map is read);
  // alone it must be a float
  j["lights"] = json::array({{{"type", "environment"}, {"map", "sky.exr"}, {"scale", 1e39}}});
  EXPECT_SCENE_ERROR(j, "/lights/0/scale", "value 1e+39 is beyond the largest float");
  // a disc's radiance is irradiance / (pi sin^2(angle / 2)): a tiny disc overflows it, and its pdf
  j["lights"] = json::array({{{"type", "directional"}, {"to_light", {0, 1, 0}}, {"irradiance", {1e10, 1, 1}},
                              {"angle_deg", 1e-4}}});
  EXPECT_SCENE_ERROR(j, "/lights/0/irradiance", "is a radiance of");
  j["lights"] = json::array({{{"type", "directional"}, {"to_light", {0, 1, 0}}, {"angle_deg", 1e-12}}});
  EXPECT_SCENE_ERROR(j, "/lights/0/angle_deg", "too small");
  // a delta sun's bound includes the scene's sharpest phase function
  j = example();
  j["lights"] = json::array({{{"type", "directional"}, {"to_light", {0, 1, 0}}, {"irradiance", {1e16, 1, 1}}}});
  j["media"][0]["phase"] = {{"type", "hg"}, {"g", 0.999}};
  EXPECT_SCENE_ERROR(j, "/lights/0/irradiance", "largest phase-function value");
  j["media"][0]["phase"] = {{"type", "isotropic"}};
  EXPECT_NO_THROW(parse(j));
}

TEST_F(SceneTest, EmissionThatOverflowsFloatIsRefused) {
  json j = example();
  j["media"][0]["emission"] = {{"radiance", {1e19, 1, 1}}, {"scale", 100}};
  EXPECT_SCENE_ERROR(j, "/media/0/emission", "radiance x scale = 1e+21");
  // the product density x sigma_a x Le, once the grids' largest values are known
  MediumDesc m;
  m.name = "hot";
  m.sigma_a = {2, 1, 1};
  m.emission.present = true;
  m.emission.radiance = {1e10, 1, 1};
  EXPECT_NO_THROW(check_emission_bounds("s.json: /media/0", m, 1e3, 1e3));
  EXPECT_THAT([&] { try { check_emission_bounds("s.json: /media/0", m, 1e20, 1.0); } catch (const Error& e) { return std::string(e.what()); } return std::string(); }(),
              StartsWith("s.json: /media/0/emission: sigma_a x density_scale x the density grid's largest value"));
  EXPECT_THAT([&] { try { check_emission_bounds("s.json: /media/0", m, 1.0, 1e11); } catch (const Error& e) { return std::string(e.what()); } return std::string(); }(),
              HasSubstr("the emission grid's largest value"));
}

TEST_F(SceneTest, HgAsymmetryThatRoundsToOneInFloatIsRefused) {
  json j = example();
  j["media"][0]["phase"] = {{"type", "hg"}, {"g", 0.99999999999}};
  EXPECT_SCENE_ERROR(j, "/media/0/phase/g", "rounds to 1 in single precision");
  j["media"][0]["phase"]["g"] = -0.999999999;
  EXPECT_SCENE_ERROR(j, "/media/0/phase/g", "rounds to -1");
  j["media"][0]["phase"]["g"] = 0.9999;
  EXPECT_NO_THROW(parse(j));
}

TEST_F(SceneTest, LargeButRepresentableLightsAreAccepted) {
  json j = example();
  j["lights"] = json::array({{{"type", "environment"}, {"radiance", {1e18, 1e18, 1e18}}},
                             {{"type", "directional"}, {"to_light", {0, 1, 0}}, {"irradiance", {1e17, 1, 1}}},
                             {{"type", "directional"}, {"to_light", {1, 1, 0}}, {"angle_deg", 0.53}}});
  EXPECT_NO_THROW(parse(j));
}

TEST_F(SceneTest, InputsThatAreNotRegularFilesAreRefused) {
  const fs::path fifo = dir_ / "pipe.vdb";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  json j = example();
  j["media"][0]["file"] = "pipe.vdb";
  EXPECT_SCENE_ERROR(j, "/media/0/file", "is a FIFO (named pipe), not a regular file");
  j = example();
  j["lights"][0] = {{"type", "environment"}, {"map", "/dev/zero"}};
  EXPECT_SCENE_ERROR(j, "/lights/0/map", "/dev/zero: is a character device");
  // the loaders refuse them too, whoever calls them
  EXPECT_THAT([&] { try { load_float_grid(fifo.string(), "density", -1, "ctx"); } catch (const Error& e) { return std::string(e.what()); } return std::string(); }(),
              HasSubstr("ctx: " + fifo.string() + ": is a FIFO"));
  EXPECT_THROW(read_image(fifo.string()), Error);
  try {
    load_scene("/dev/zero");
    ADD_FAILURE() << "/dev/zero accepted as a scene";
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), StartsWith("/dev/zero: is a character device"));
  }
}

// OpenEXR allocates what a header attribute claims before it finds the file short: read_image
// walks the header first (a fuzz finding: a "capDate" string claiming 1.9 GB made OpenEXR allocate it)
TEST_F(SceneTest, DamagedExrHeaderIsRefusedBeforeOpenExrReadsIt) {
  const std::string good = (dir_ / "good.exr").string();
  write_image(good, 4, 2, std::vector<float>(4 * 2 * 3, 0.5f), {{"spectrack:spp", 3}});
  RgbImage img = read_image(good);
  EXPECT_EQ(img.width, 4);
  EXPECT_EQ(img.height, 2);
  std::ifstream in(good, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  // the first attribute is "channels" of type "chlist"; its size follows the two names
  const size_t size_at = bytes.find("chlist");
  ASSERT_NE(size_at, std::string::npos);
  std::string b = bytes;
  b[size_at + 7] = '\x00', b[size_at + 8] = '\x00', b[size_at + 9] = '\x00', b[size_at + 10] = '\x73';  // 1.9 GB
  EXPECT_THAT(image_error("huge.exr", b), StartsWith((dir_ / "huge.exr").string() +
                                                 ": damaged OpenEXR header: attribute 'channels' (chlist) claims"));
  b = bytes;
  b[size_at + 10] = '\x80';  // negative
  EXPECT_THAT(image_error("negative.exr", b), HasSubstr("attribute 'channels' (chlist) claims -"));
  EXPECT_THAT(image_error("cut.exr", bytes.substr(0, size_at + 2)), HasSubstr("damaged OpenEXR header: the file ends inside"));
  b = bytes;
  b[5] |= 0x10;  // the multi-part flag on a single-part file: refused, by the walk or by OpenEXR
  EXPECT_THAT(image_error("parts.exr", b), StartsWith((dir_ / "parts.exr").string() + ": "));
  // a fixed-size attribute claiming another size (a fuzz finding: a v2f claiming 0 bytes; OpenEXR
  // reads its 8 bytes anyway, so the walk and OpenEXR parted ways and OpenEXR read a 2 GB string)
  const size_t v2f_at = bytes.find("v2f");
  ASSERT_NE(v2f_at, std::string::npos);
  b = bytes;
  b[v2f_at + 4] = '\x00';  // its size 8 -> 0
  EXPECT_THAT(image_error("fixed.exr", b), HasSubstr("claims 0 bytes, but a v2f value has 8"));
  // a channel list shorter than its channels (OpenEXR reads the list to its end, not the claim)
  b = bytes;
  b[size_at + 7] = char(b[size_at + 7] - 2);
  EXPECT_THAT(image_error("chlist.exr", b), HasSubstr("attribute 'channels' (chlist) runs past the"));
  b = bytes;
  b[size_at + 7] = char(b[size_at + 7] + 2);
  EXPECT_THAT(image_error("chlist2.exr", b), HasSubstr("but its contents take"));
  // a data window far wider than the file could hold (a fuzz finding: OpenEXR sized a 2 GB
  // decompressor buffer by it when the file was opened, before any pixel was read)
  const size_t window_at = bytes.find("dataWindow");
  ASSERT_NE(window_at, std::string::npos);
  ASSERT_EQ(bytes.substr(window_at + 11, 6), std::string("box2i\0", 6));
  const size_t x_max_at = window_at + 11 + 6 + 4 + 8;  // the names, the size, then xMin and yMin
  b = bytes;
  b[x_max_at] = '\x00', b[x_max_at + 1] = '\x00', b[x_max_at + 2] = '\x40', b[x_max_at + 3] = '\x00';  // 4 M pixels wide
  EXPECT_THAT(image_error("wide.exr", b), StartsWith((dir_ / "wide.exr").string() +
                                                 ": damaged OpenEXR header: its data window (4194305 x 2 pixels) claims more"));
  b[x_max_at + 2] = '\x00', b[x_max_at + 1] = '\x01';  // 257 pixels wide: within the bound, so OpenEXR reads it
  EXPECT_THAT(image_error("wider.exr", b), AllOf(HasSubstr("wider.exr"), Not(HasSubstr("pixels a byte"))));
}

// libpng allocates what a chunk's length claims before it reads the chunk: read_image walks the
// chunks first (a fuzz finding: a tEXt chunk claiming 1.7 GB took 2 GB and 14 s under ASan)
TEST_F(SceneTest, DamagedPngChunkIsRefusedBeforeLibpngReadsIt) {
  const std::string good = (dir_ / "good.png").string();
  write_image(good, 4, 2, std::vector<float>(4 * 2 * 3, 0.5f), {});
  RgbImage img = read_image(good);
  EXPECT_EQ(img.width, 4);
  EXPECT_EQ(img.height, 2);
  std::ifstream in(good, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  ASSERT_EQ(bytes.substr(12, 4), "IHDR");
  const size_t after_ihdr = 8 + 8 + 13 + 4;  // signature, IHDR length and type, data, CRC
  std::string b = bytes;
  b.insert(after_ihdr, std::string("\x66\x00\x00\x19tEXtspectrack", 17));
  EXPECT_THAT(image_error("huge.png", b), StartsWith((dir_ / "huge.png").string() +
                                                 ": damaged PNG file: chunk 1 ('tEXt') claims 1711276057 bytes"));
  b = bytes;
  b[after_ihdr] = '\x80';  // more than PNG's 2^31 - 1
  EXPECT_THAT(image_error("negative.png", b), HasSubstr("damaged PNG file: chunk 1 ("));
  EXPECT_THAT(image_error("cut.png", bytes.substr(0, after_ihdr + 3)), HasSubstr("damaged PNG file: the file ends inside"));
}

TEST_F(SceneTest, ReadInputFileStopsAtItsBound) {
  const fs::path f = dir_ / "ten.json";
  std::ofstream(f) << "0123456789";
  EXPECT_EQ(read_input_file(f.string(), "", 10), "0123456789");
  EXPECT_THAT([&] { try { read_input_file(f.string(), "ctx", 9); } catch (const Error& e) { return std::string(e.what()); } return std::string(); }(),
              StartsWith("ctx: " + f.string() + ": is 10 bytes, more than the 9"));
  // a /proc file says size 0 but holds more: the read itself stops at the bound
  EXPECT_THROW(read_input_file("/proc/self/maps", "", 16), Error);
}

TEST_F(SceneTest, SameFileComparesWhatPathsName) {
  const std::string a = (dir_ / "a.exr").string();
  EXPECT_TRUE(same_file(a, (dir_ / "." / "a.exr").string()));
  EXPECT_TRUE(same_file(a, (dir_ / "sub" / ".." / "a.exr").string()));
  EXPECT_FALSE(same_file(a, (dir_ / "b.exr").string()));
  fs::create_symlink(a, dir_ / "dangling.exr");  // a.exr does not exist yet: writing the link creates it
  EXPECT_TRUE(same_file(a, (dir_ / "dangling.exr").string()));
  std::ofstream(a) << "x";
  fs::create_hard_link(a, dir_ / "hard.exr");
  EXPECT_TRUE(same_file(a, (dir_ / "hard.exr").string()));
  EXPECT_TRUE(same_file((dir_ / "dangling.exr").string(), (dir_ / "hard.exr").string()));
  try {
    check_distinct_paths({{"the image", a}, {"--preview", ""}, {"--stats-json", (dir_ / "hard.exr").string()}}, {});
    ADD_FAILURE() << "colliding outputs accepted";
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), HasSubstr("the image " + a + " and --stats-json"));
    EXPECT_THAT(e.what(), HasSubstr("name the same file"));
  }
  EXPECT_THROW(check_distinct_paths({{"the image", (dir_ / "x.exr").string()}}, {{"the scene file", (dir_ / "x.exr").string()}}), Error);
  EXPECT_NO_THROW(check_distinct_paths({{"the image", a}, {"--preview", (dir_ / "a.png").string()}}, {{"the scene file", (dir_ / "s.json").string()}}));
}

}  // namespace
}  // namespace spectrack

TEST(SceneHostile, HugeArraysAreRefusedQuickly) {
  std::string text = "{\"format\":\"spectrack-scene/1\",\"media\":[";
  for (int i = 0; i < 200000; ++i) text += (i ? ",{}" : "{}");
  text += "]}";
  auto t0 = std::chrono::steady_clock::now();
  try {
    spectrack::parse_scene(text, "huge.json", "/tmp");
    ADD_FAILURE() << "must be refused";
  } catch (const spectrack::Error& e) {
    EXPECT_NE(std::string(e.what()).find("huge.json"), std::string::npos) << e.what();
  }
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 2.0);
}
