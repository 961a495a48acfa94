// test_shipped_scenes.cpp: the scenes the repository ships (data/scenes, docs/examples) work from a
// fresh clone, or say what is missing and where to get it.
//
// Design: a medium whose `file` resolves outside the source tree is third-party data, which the
// repository never holds; such a medium must carry `file_source` (where to download the file, its
// licence), and rendering the scene where the file is absent must fail (exit 1) with an error that
// names the file and quotes that advice, not with a bare missing path. The test renders a copy of
// each such scene in a temporary folder, where the repository's own files are given by absolute
// path and the third-party ones keep their relative path, which then resolves nowhere (as in a clone
// without the shared data beside it). Its twin removes a `file_source` and must see both checks
// fail. The default scene (scripts/render-default.sh) needs no third-party file at all, and the
// render settings it holds (render.adaptive) take effect without flags.
#include <OpenImageIO/imageio.h>

#include <algorithm>

#include "cli_util.h"

namespace {

using namespace st_cli;
using json = nlohmann::json;
const fs::path kSrc = fs::path(SPECTRACK_SOURCE_DIR).lexically_normal();

std::vector<fs::path> shipped_scenes() {
  std::vector<fs::path> out;
  for (const char* d : {"data/scenes", "docs/examples"})
    for (auto& e : fs::directory_iterator(kSrc / d))
      if (e.path().extension() == ".json") out.push_back(e.path());
  std::sort(out.begin(), out.end());
  return out;
}

json read_json(const fs::path& p) {
  std::ifstream f(p);
  return json::parse(f);
}

fs::path resolved(const fs::path& scene_path, const std::string& file) {
  const fs::path f(file);
  return (f.is_absolute() ? f : scene_path.parent_path() / f).lexically_normal();
}

bool inside_repository(const fs::path& p) {
  const fs::path rel = p.lexically_relative(kSrc);
  return !rel.empty() && *rel.begin() != "..";
}

// The indices of the media of `scene` (read from `path`) whose file lies outside the repository.
std::vector<size_t> third_party_media(const json& scene, const fs::path& path) {
  std::vector<size_t> out;
  for (size_t i = 0; i < scene.value("media", json::array()).size(); ++i) {
    const json& m = scene["media"][i];
    if (m.contains("file") && !inside_repository(resolved(path, m["file"].get<std::string>()))) out.push_back(i);
  }
  return out;
}

// One line per third-party medium of `scene` that does not say where to get its file.
std::vector<std::string> missing_sources(const json& scene, const fs::path& path) {
  std::vector<std::string> out;
  for (size_t i : third_party_media(scene, path)) {
    const json& m = scene["media"][i];
    if (!m.contains("file_source") || !m["file_source"].is_string() || m["file_source"].get<std::string>().size() < 20)
      out.push_back(path.string() + ": /media/" + std::to_string(i) + " reads " + m["file"].get<std::string>() +
                    ", which the repository does not hold, and has no file_source saying where to get it");
  }
  return out;
}

// Renders a copy of `scene` in `dir` without its third-party files (see the design note).
Proc render_without_third_party(json scene, const fs::path& path, const std::string& dir) {
  for (json& m : scene["media"])
    if (m.contains("file")) {
      const fs::path f = resolved(path, m["file"].get<std::string>());
      if (inside_repository(f)) m["file"] = f.string();
    }
  const std::string copy = write_scene(dir, path.filename().string(), scene);
  return run({"render", copy, "--spp", "1", "-o", dir + "/out.exr", "--quiet"});
}

// The failures of the two checks on one scene, as messages (empty: it passes).
std::vector<std::string> check_scene(const json& scene, const fs::path& path, const std::string& dir) {
  std::vector<std::string> out = missing_sources(scene, path);
  const std::vector<size_t> tp = third_party_media(scene, path);
  if (tp.empty()) return out;
  const Proc p = render_without_third_party(scene, path, dir);
  const json& m = scene["media"][tp[0]];
  const std::string file = fs::path(m["file"].get<std::string>()).filename().string();
  std::vector<std::string> words = {"/media/" + std::to_string(tp[0]) + "/file", file, "no such file",
                                    "third-party data, not in the repository"};
  if (m.contains("file_source")) words.push_back(m["file_source"].get<std::string>());
  if (!(p.exited && p.code == 1)) out.push_back("expected exit 1: " + p.describe());
  for (const std::string& w : words)
    if (p.out.find(w) == std::string::npos) out.push_back("the error does not say \"" + w + "\": " + p.describe());
  if (fs::exists(dir + "/out.exr")) out.push_back("an image was written: " + p.describe());
  return out;
}

TEST(ShippedScenes, ThirdPartyFilesSayWhereToGetThem) {
  const std::string dir = test_dir();
  size_t third_party = 0;
  for (const fs::path& p : shipped_scenes()) {
    SCOPED_TRACE(p.string());
    const json scene = read_json(p);
    if (!third_party_media(scene, p).empty()) ++third_party;
    for (const std::string& e : check_scene(scene, p, dir)) ADD_FAILURE() << e;
  }
  EXPECT_GE(third_party, 2u) << "data/scenes holds the Disney cloud and OpenUSD's fire: the check must see them";
}

// The twin: the Disney cloud's scene without its file_source fails both checks.
TEST(ShippedScenes, CheckSeesAMissingSource) {
  const std::string dir = test_dir();
  const fs::path p = kSrc / "data/scenes/disney_cloud.json";
  json scene = read_json(p);
  ASSERT_TRUE(check_scene(scene, p, dir).empty());
  scene["media"][0].erase("file_source");
  const std::vector<std::string> e = check_scene(scene, p, dir);
  EXPECT_EQ(e.size(), 2u) << "a missing file_source and an error without the advice";
  for (const std::string& s : e) std::cout << "found as expected: " << s.substr(0, 160) << "\n";
}

// The first command renders a scene that the build makes whole: no third-party file.
TEST(ShippedScenes, DefaultSceneNeedsNoThirdPartyData) {
  std::ifstream f(kSrc / "scripts/render-default.sh");
  std::stringstream s;
  s << f.rdbuf();
  const std::string script = s.str();
  const std::string scene = "data/scenes/sunset_smoke.json";
  ASSERT_NE(script.find(scene), std::string::npos) << "render-default.sh renders another scene: update this test";
  const json j = read_json(kSrc / scene);
  EXPECT_TRUE(third_party_media(j, kSrc / scene).empty());
}

// The default scene asks for adaptive sampling in the scene (render.adaptive), not on the command
// line: that field must be honoured without --adaptive, and its twin, the same scene without the
// field, must render uniformly (no per-pixel sample counts).
TEST(ShippedScenes, SceneAdaptiveFieldIsHonoured) {
  const std::string dir = test_dir();
  json scene = homogeneous_scene(16, 16, 64, 1.0, 0.1);
  scene["render"]["noise_target"] = 0.2;
  for (bool adaptive : {true, false}) {
    SCOPED_TRACE(adaptive ? "render.adaptive true" : "no render.adaptive");
    if (adaptive) scene["render"]["adaptive"] = true;
    else scene["render"].erase("adaptive");
    const std::string path = write_scene(dir, "adaptive.json", scene);
    const std::string out = dir + (adaptive ? "/a.exr" : "/u.exr");
    RunOptions o;
    o.timeout_s = 600;  // a cold kernel build on a loaded machine
    const Proc p = run({"render", path, "-o", out, "--generic-kernels", "--quiet"}, o);
    ASSERT_TRUE(p.exited && p.code == 0) << p.describe();
    auto in = OIIO::ImageInput::open(out);
    ASSERT_TRUE(in) << out;
    const OIIO::ImageSpec& spec = in->spec();
    const bool has_samples = std::find(spec.channelnames.begin(), spec.channelnames.end(), "samples") != spec.channelnames.end();
    EXPECT_EQ(has_samples, adaptive);
    EXPECT_EQ(spec.get_int_attribute("spectrack:adaptive", 0), adaptive ? 1 : 0);
  }
}

}  // namespace
