// test_denoise.cpp: --denoise (image/denoise.h), Intel Open Image Denoise as an optional extra.
//
// Design: without the library (SPECTRACK_OIDN_LIBRARY naming a file that does not exist) the flag
// exits 2 before rendering, saying how to get it, and renders without the flag are untouched. With
// pyoidn installed (the tests skip, saying why, when it is not), a 16-spp render gets the
// denoised.R/G/B layer, its R, G, B stay the plain render's, and the denoised beauty is closer to a
// long render than the noisy one (relative mean squared error), which a denoiser that returned its
// input, or noise, would not be.
#include <OpenImageIO/imageio.h>

#include <cmath>
#include <cstdlib>

#include "cli_util.h"
#include "film/film.h"
#include "image/denoise.h"

namespace {

using namespace st_cli;

json denoise_scene(const std::string& dir) { return small_noise_scene(dir, 48, 32); }

// The named channels of an EXR, pixel-major.
std::vector<float> channels_of(const std::string& path, const std::vector<std::string>& names) {
  auto in = OIIO::ImageInput::open(path);
  EXPECT_TRUE(in) << path;
  if (!in) return {};
  const auto& spec = in->spec();
  std::vector<float> px(size_t(spec.width) * spec.height * spec.nchannels), out;
  in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, px.data());
  std::vector<int> idx;
  for (const std::string& n : names) {
    const auto it = std::find(spec.channelnames.begin(), spec.channelnames.end(), n);
    EXPECT_NE(it, spec.channelnames.end()) << path << " has no channel " << n;
    if (it == spec.channelnames.end()) return {};
    idx.push_back(int(it - spec.channelnames.begin()));
  }
  for (size_t i = 0; i < size_t(spec.width) * spec.height; ++i)
    for (int k : idx) out.push_back(px[i * spec.nchannels + size_t(k)]);
  return out;
}

double relative_mse(const std::vector<float>& a, const std::vector<float>& ref) {
  double e = 0, r = 0;
  for (size_t i = 0; i < ref.size(); ++i) e += (a[i] - ref[i]) * double(a[i] - ref[i]), r += double(ref[i]) * ref[i];
  return e / std::max(r, 1e-30);
}

TEST(CliDenoise, WithoutTheLibraryExitsTwoAndSaysHowToGetIt) {
  const std::string dir = test_dir();
  const std::string scene = write_scene(dir, "scene.json", denoise_scene(dir));
  ::setenv("SPECTRACK_OIDN_LIBRARY", (dir + "/no-such-libOpenImageDenoise.so.2").c_str(), 1);
  Proc p = run({"render", scene, "-o", dir + "/d.exr", "--spp", "2", "--denoise", "--quiet"});
  ::unsetenv("SPECTRACK_OIDN_LIBRARY");
  EXPECT_EQ(p.code, 2) << p.describe();
  EXPECT_THAT(p.out, HasSubstr("pip install"));
  EXPECT_THAT(p.out, HasSubstr("no-such-libOpenImageDenoise.so.2', which does not exist"));
  EXPECT_FALSE(fs::exists(dir + "/d.exr"));
  p = run({"render", scene, "-o", dir + "/d.png", "--spp", "2", "--denoise", "--quiet"});
  EXPECT_EQ(p.code, 2) << p.describe();  // a layer needs an EXR
}

TEST(CliDenoise, TheDenoisedLayerIsCloserToALongRenderThanTheNoisyBeauty) {
  if (spectrack::find_oidn_library().empty())
    GTEST_SKIP() << "Intel Open Image Denoise is not installed (/usr/bin/python3 -m pip install --user pyoidn)";
  const std::string dir = test_dir();
  const std::string scene = write_scene(dir, "scene.json", denoise_scene(dir));
  RunOptions ro;
  ro.timeout_s = 300;
  Proc p = run({"render", scene, "-o", dir + "/d.exr", "--spp", "8", "--denoise", "--no-alpha", "--quiet"}, ro);
  ASSERT_TRUE(p.exited && p.code == 0) << p.describe();
  p = run({"render", scene, "-o", dir + "/plain.exr", "--spp", "8", "--no-alpha", "--quiet"}, ro);
  ASSERT_TRUE(p.exited && p.code == 0) << p.describe();
  p = run({"render", scene, "-o", dir + "/ref.exr", "--spp", "512", "--seed", "7", "--no-alpha", "--quiet"}, ro);
  ASSERT_TRUE(p.exited && p.code == 0) << p.describe();
  const std::vector<float> noisy = channels_of(dir + "/d.exr", {"R", "G", "B"});
  const std::vector<float> denoised = channels_of(dir + "/d.exr", {"denoised.R", "denoised.G", "denoised.B"});
  const std::vector<float> plain = channels_of(dir + "/plain.exr", {"R", "G", "B"});
  const std::vector<float> ref = channels_of(dir + "/ref.exr", {"R", "G", "B"});
  ASSERT_EQ(denoised.size(), ref.size());
  ASSERT_EQ(noisy.size(), plain.size());
  for (size_t i = 0; i < plain.size(); ++i)  // the albedo layer adds the environment back in another order
    ASSERT_NEAR(noisy[i], plain[i], 1e-5 * std::max(1.0f, std::abs(plain[i]))) << "R, G, B stay the render's: value " << i;
  const double e_noisy = relative_mse(noisy, ref), e_denoised = relative_mse(denoised, ref);
  EXPECT_LT(e_denoised, 0.5 * e_noisy) << "denoised " << e_denoised << " noisy " << e_noisy;
  auto in = OIIO::ImageInput::open(dir + "/d.exr");
  ASSERT_TRUE(in);
  EXPECT_EQ(in->spec().get_string_attribute("spectrack:denoised"), "oidn RT, albedo");
  // read back as a piece (Python's spectrack.read), the denoised layer comes with it, value for value
  const spectrack::FilmPiece piece = spectrack::read_piece(dir + "/d.exr");
  ASSERT_EQ(piece.denoised.size(), denoised.size());
  for (size_t i = 0; i < denoised.size(); ++i) ASSERT_EQ(piece.denoised[i], denoised[i]) << "value " << i;
  EXPECT_TRUE(spectrack::read_piece(dir + "/plain.exr").denoised.empty());
}

}  // namespace
