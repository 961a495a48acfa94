// test_aov.cpp: the film layers (docs/aov.md): alpha from a transmittance estimate
// along the camera ray (closed form on a slab, exactly 0 where the ray meets nothing, 1 behind an
// opaque medium), the transparent film (R, G, B + environment = the beauty), the variance layer
// against the variance computed from single-sample shards of the same render, exact merging of
// every layer, the EXR channels (names, alpha channel, half, compression) and the scene fields.
#include <OpenImageIO/imageio.h>

#include <cmath>

#include "image/image.h"
#include "film/film.h"
#include "integrator/renderer.h"
#include "color/spectrum.h"
#include "test_util.h"

using namespace spectrack;
using namespace st_test;
using nlohmann::json;

namespace {

json base(int w, int h, int spp, const std::string& tracker, double cam_height = 1.0) {
  return json{{"format", "spectrack-scene/1"},
              {"camera",
               {{"type", "orthographic"}, {"position", {0, 0, -3}}, {"look_at", {0, 0, 0}}, {"up", {0, 1, 0}}, {"height", cam_height}}},
              {"film", {{"width", w}, {"height", h}, {"spp", spp}}},
              {"render", {{"tracker", tracker}, {"seed", 11}}},
              {"lights", json::array({{{"type", "environment"}, {"radiance", {0.5, 1.0, 2.0}}}})},
              {"media", json::array()}};
}

// An absorbing box [-1, 1]^3 seen along z: every camera ray crosses 2 units, T_c = exp(-2 sigma_a_c).
json slab(const std::string& tracker, int spp, double cam_height = 1.0, double scale = 1.0) {
  json s = base(16, 16, spp, tracker, cam_height);
  s["media"].push_back({{"type", "homogeneous"}, {"bounds", {{-1, -1, -1}, {1, 1, 1}}},
                        {"sigma_a", {0.5 * scale, 1.0 * scale, 2.0 * scale}}, {"sigma_s", {0, 0, 0}}});
  return s;
}

// The lumpy VDB under the environment and a sun: scattering, chromatic, heterogeneous.
json lumpy(const std::string& dir, const std::string& tracker, int spp) {
  write_lumpy(dir + "/lumpy.vdb");
  json s = base(12, 10, spp, tracker, 2.4);
  s["lights"].push_back({{"type", "directional"}, {"to_light", {-0.4, 1.0, -0.3}}, {"irradiance", {2, 2, 2}}});
  s["media"].push_back({{"type", "vdb"}, {"file", "lumpy.vdb"}, {"density_scale", 5.0}, {"sigma_a", {0.1, 0.2, 0.4}},
                        {"sigma_s", {1.2, 0.8, 0.5}}, {"phase", {{"type", "hg"}, {"g", 0.3}}}});
  return s;
}

RenderOptions with_layers(uint32_t aovs, int spp = -1) {
  RenderOptions o = quiet_options(spp);
  o.aovs = aovs;
  return o;
}

constexpr uint32_t kAll = ST_AOV_BIT(ALPHA) | ST_AOV_BIT(ENVIRONMENT) | ST_AOV_BIT(VARIANCE);

// Per-pixel means of channel `name` of a result's layers.
std::vector<double> layer(const RenderResult& r, const std::string& name) {
  const size_t na = r.aov_channels.size();
  const size_t c = size_t(std::find(r.aov_channels.begin(), r.aov_channels.end(), name) - r.aov_channels.begin());
  EXPECT_LT(c, na) << name;
  std::vector<double> v(size_t(r.width) * r.height);
  for (size_t i = 0; i < v.size() && c < na; ++i) v[i] = r.aov_sum[i * na + c] / double(r.spp_done);
  return v;
}

}  // namespace

TEST(Aov, SlabAlphaIsOneMinusTransmittanceForEveryTracker) {
  const std::string dir = temp_dir("aov_slab");
  const double tau[3] = {1.0, 2.0, 4.0};
  for (const char* tracker : {"delta-per-channel", "spectral", "spectral-mis", "decomposition", "spectral-decomposition"})
    for (int tm : {int(ST_TRANSMITTANCE_RATIO), int(ST_TRANSMITTANCE_RAY_MARCHING)}) {
      SCOPED_TRACE(std::string(tracker) + " / " + transmittance_name(tm));
      RenderOptions o = with_layers(ST_AOV_BIT(ALPHA), 64);
      o.transmittance = tm;
      Renderer r(scene_from_json(slab(tracker, 64), dir), o);
      EXPECT_TRUE(r.features() & ST_FEATURE_AOV);
      RenderResult res = r.render();
      ASSERT_EQ(res.aov_channels, (std::vector<std::string>{"AR", "AG", "AB", "environment.R", "environment.G", "environment.B"}));
      const char* a[3] = {"AR", "AG", "AB"};
      const char* e[3] = {"environment.R", "environment.G", "environment.B"};
      const double env[3] = {0.5, 1.0, 2.0};
      for (int c = 0; c < 3; ++c) {
        Stats s = mean_se(layer(res, a[c]));
        EXPECT_NEAR(s.mean, 1.0 - std::exp(-tau[c]), 4.0 * s.se + 1e-5) << "channel " << c << " SE " << s.se;
        // nothing scatters or emits: the transparent R, G, B hold nothing, the environment layer all
        for (size_t i = 0; i < size_t(res.width) * res.height; ++i) EXPECT_EQ(res.rgb[i * 3 + c], 0.0f);
        Stats se = mean_se(layer(res, e[c]));
        EXPECT_NEAR(se.mean, env[c] * std::exp(-tau[c]), 4.0 * se.se + 1e-5) << "channel " << c;
      }
    }
}

TEST(Aov, SlabAlphaDetectsAWrongTransmittance) {
  // the same check against a 5% wrong answer must fail: the test above can fail
  const std::string dir = temp_dir("aov_slab_wrong");
  Renderer r(scene_from_json(slab("spectral", 64), dir), with_layers(ST_AOV_BIT(ALPHA), 64));
  RenderResult res = r.render();
  Stats s = mean_se(layer(res, "AG"));
  EXPECT_GT(std::abs(s.mean - (1.0 - std::exp(-2.0)) * 1.05), 4.0 * s.se);
}

TEST(Aov, AlphaIsZeroExactlyWhereTheRayMeetsNothingAndOneBehindAnOpaqueMedium) {
  const std::string dir = temp_dir("aov_edges");
  for (const char* tracker : {"delta-per-channel", "spectral", "spectral-decomposition"}) {
    SCOPED_TRACE(tracker);
    // the camera sees 4 units across, the box covers the middle half
    Renderer r(scene_from_json(slab(tracker, 8, 4.0), dir), with_layers(ST_AOV_BIT(ALPHA), 8));
    RenderResult res = r.render();
    const size_t na = res.aov_channels.size();
    int outside = 0;
    for (int y = 0; y < res.height; ++y)
      for (int x = 0; x < res.width; ++x) {
        if (x >= 3 && x < 13 && y >= 3 && y < 13) continue;  // pixels that may touch the box (4 px = 1 unit)
        const size_t i = size_t(y) * res.width + x;
        for (int c = 0; c < 3; ++c) {
          EXPECT_EQ(res.aov_sum[i * na + c], 0.0) << x << "," << y;                                  // A = 0 exactly
          EXPECT_EQ(res.aov_sum[i * na + 3 + c], 8.0 * (c == 0 ? 0.5 : c == 1 ? 1.0 : 2.0)) << x << "," << y;  // the environment
        }
        ++outside;
      }
    EXPECT_GT(outside, 100);
    // sigma_a x 50: T = exp(-100) and below: A = 1
    Renderer opaque(scene_from_json(slab(tracker, 8, 1.0, 50.0), dir), with_layers(ST_AOV_BIT(ALPHA), 8));
    RenderResult o = opaque.render();
    for (const char* c : {"AR", "AG", "AB"})
      for (double v : layer(o, c)) EXPECT_NEAR(v, 1.0, 1e-6) << c;
  }
}

TEST(Aov, LayersLeaveTheBeautyAndItsStatisticsAlone) {
  const std::string dir = temp_dir("aov_beauty");
  for (const char* tracker : {"delta-per-channel", "spectral-decomposition"}) {
    SCOPED_TRACE(tracker);
    const SceneDesc scene = scene_from_json(lumpy(dir, tracker, 6), dir);
    RenderResult plain = Renderer(scene, quiet_options()).render();
    Renderer lr(scene, with_layers(kAll));
    RenderResult all = lr.render();
    EXPECT_TRUE(lr.features() & ST_FEATURE_AOV);
    // the paths draw the same numbers: the same collisions and lookups, the image to float rounding
    EXPECT_EQ(all.stats.lookups_track, plain.stats.lookups_track);
    EXPECT_EQ(all.stats.lookups_shadow, plain.stats.lookups_shadow);
    EXPECT_EQ(plain.stats.lookups_alpha, 0u);
    EXPECT_GT(all.stats.lookups_alpha, 0u);
    const size_t na = all.aov_channels.size();
    for (size_t i = 0; i < plain.sum.size(); ++i) {
      const double whole = all.sum[i] + all.aov_sum[(i / 3) * na + 3 + i % 3];  // transparent RGB + environment
      EXPECT_NEAR(whole, plain.sum[i], 1e-5 * std::max(1.0, std::abs(plain.sum[i]))) << i;
    }
    // the generic kernel renders the same layers (one tracker: its build is the slow part)
    if (std::string(tracker) == "spectral-decomposition") {
      RenderOptions g = with_layers(kAll);
      g.generic_kernels = true;
      RenderResult gen = Renderer(scene, g).render();
      EXPECT_EQ(gen.aov_sum, all.aov_sum);
      EXPECT_EQ(gen.sum, all.sum);
    }
    // variance only: no per-path layer work, the feature bit stays off, the beauty is bit-identical
    Renderer vr(scene, with_layers(ST_AOV_BIT(VARIANCE)));
    EXPECT_FALSE(vr.features() & ST_FEATURE_AOV);
    RenderResult v = vr.render();
    EXPECT_EQ(v.sum, plain.sum);
  }
}

TEST(Aov, VarianceLayerEqualsTheVarianceOfTheSamples) {
  // The render's samples one by one (single-sample shards of the same sequence), their variance
  // of the mean per pixel, against the variance layer of one render of all of them.
  const std::string dir = temp_dir("aov_variance");
  const int n = 6;
  const SceneDesc scene = scene_from_json(lumpy(dir, "spectral", n), dir);
  Renderer r(scene, with_layers(ST_AOV_BIT(VARIANCE) | ST_AOV_BIT(ALPHA)));
  RenderResult all = r.render();
  std::vector<RenderResult> one;
  for (int s = 0; s < n; ++s) one.push_back(r.render(s, 1));
  const size_t npix = size_t(all.width) * all.height, na = all.aov_channels.size();
  const size_t e = 3, v = 6;  // environment.*, moment2.* in aov_sum_channels order
  FilmPiece piece = piece_from_result(all, render_identity(r.settings()), "all");
  const std::string exr = dir + "/v.exr";
  write_piece(exr, piece, {});
  auto in = OIIO::ImageInput::open(exr);
  ASSERT_TRUE(in);
  const OIIO::ImageSpec spec = in->spec();
  std::vector<float> px(npix * size_t(spec.nchannels));
  ASSERT_TRUE(in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, px.data()));
  int nonzero = 0;
  for (int c = 0; c < 3; ++c) {
    const int vc = spec.channelindex(std::string("variance.") + "RGB"[c]);
    ASSERT_GE(vc, 0);
    for (size_t i = 0; i < npix; ++i) {
      std::vector<double> x;
      for (auto& o : one) x.push_back(o.sum[i * 3 + c] + o.aov_sum[i * na + e + c]);  // each sample's whole beauty
      Stats st = mean_se(x);
      const double expected = st.se * st.se;
      double m2 = 0;
      for (double xi : x) m2 += xi * xi;
      EXPECT_NEAR(all.aov_sum[i * na + v + c], m2, 1e-5 * std::max(1.0, m2)) << "pixel " << i;
      EXPECT_NEAR(px[i * spec.nchannels + vc], expected, 1e-4 * std::max(expected, 1e-3)) << "pixel " << i << " channel " << c;
      nonzero += expected > 0;
    }
  }
  EXPECT_GT(nonzero, int(npix) / 4);  // the medium covers part of the frame
}

TEST(Aov, ShardsAndTilesMergeEveryLayerAndMismatchedLayersAreRefused) {
  const std::string dir = temp_dir("aov_merge");
  const SceneDesc scene = scene_from_json(lumpy(dir, "spectral-decomposition", 8), dir);
  Renderer full_r(scene, with_layers(kAll));
  RenderIdentity id = render_identity(full_r.settings());
  id.scene_hash = "h";
  FilmPiece full = piece_from_result(full_r.render(), id, "full");
  // sample shards through EXR files, then merged
  std::vector<FilmPiece> read;
  for (auto [b, e] : {std::pair{0, 3}, std::pair{3, 8}}) {
    FilmPiece p = piece_from_result(full_r.render(b, e - b), id, "shard");
    const std::string f = dir + "/shard" + std::to_string(b) + ".exr";
    write_piece(f, p, {});
    read.push_back(read_piece(f));
    EXPECT_EQ(read.back().id.aovs, kAll);
  }
  FilmPiece m = merge_pieces(read);
  ASSERT_EQ(m.aov_sum.size(), full.aov_sum.size());
  for (size_t i = 0; i < full.sum.size(); ++i) EXPECT_NEAR(m.sum[i], full.sum[i], 1e-5 * std::max(1.0, std::abs(full.sum[i])));
  for (size_t i = 0; i < full.aov_sum.size(); ++i)
    EXPECT_NEAR(m.aov_sum[i], full.aov_sum[i], 1e-4 * std::max(1.0, std::abs(full.aov_sum[i]))) << i;
  // pixel tiles rendered on their own
  std::vector<FilmPiece> tiles;
  for (auto [y0, y1] : {std::pair{0, 4}, std::pair{4, 10}}) {
    RenderOptions o = with_layers(kAll);
    o.pixel_bounds = std::array<int, 4>{0, 12, y0, y1};
    Renderer tr(scene, o);
    tiles.push_back(piece_from_result(tr.render(), id, "tile"));
  }
  FilmPiece mt = merge_pieces(tiles);
  EXPECT_EQ(mt.aov_sum, full.aov_sum);
  // other layers: refused, naming them
  Renderer other_r(scene, with_layers(ST_AOV_BIT(VARIANCE)));
  RenderIdentity oid = render_identity(other_r.settings());
  oid.scene_hash = "h";
  FilmPiece other = piece_from_result(other_r.render(0, 2), oid, "other");
  try {
    merge_pieces({read[0], other});
    ADD_FAILURE() << "merged pieces with different layers";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("film layers"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("alpha,environment,variance"), std::string::npos) << e.what();
  }
}

TEST(Aov, ExrChannelsAlphaHalfAndCompression) {
  const std::string dir = temp_dir("aov_exr");
  const SceneDesc scene = scene_from_json(lumpy(dir, "spectral", 4), dir);
  Renderer r(scene, with_layers(kAll));
  RenderIdentity id = render_identity(r.settings());
  id.scene_hash = "h";
  FilmPiece p = piece_from_result(r.render(), id, "p");
  ExrOptions half;
  half.half = true;
  half.compression = "dwaa";
  write_piece(dir + "/f.exr", p, {});
  write_piece(dir + "/h.exr", p, {}, half);
  write_piece(dir + "/f.png", p, {});
  auto in = OIIO::ImageInput::open(dir + "/f.exr");
  ASSERT_TRUE(in);
  const OIIO::ImageSpec spec = in->spec();
  std::vector<std::string> names(spec.channelnames.begin(), spec.channelnames.end());
  std::sort(names.begin(), names.end());
  EXPECT_EQ(names, (std::vector<std::string>{"A", "AB", "AG", "AR", "B", "G", "R", "environment.B", "environment.G",
                                             "environment.R", "variance.B", "variance.G", "variance.R"}));
  ASSERT_GE(spec.alpha_channel, 0);
  EXPECT_EQ(spec.channelnames[size_t(spec.alpha_channel)], "A");
  EXPECT_EQ(spec.format, OIIO::TypeDesc::FLOAT);
  EXPECT_EQ(spec.get_string_attribute("compression"), "zip");
  // A is the mean of AR, AG, AB; R + environment.R is the whole beauty
  std::vector<float> px(size_t(spec.width) * spec.height * spec.nchannels);
  ASSERT_TRUE(in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, px.data()));
  const int A = spec.channelindex("A"), AR = spec.channelindex("AR"), AG = spec.channelindex("AG"),
            AB = spec.channelindex("AB"), R = spec.channelindex("R"), ER = spec.channelindex("environment.R");
  double alpha_sum = 0;
  for (int i = 0; i < spec.width * spec.height; ++i) {
    const float* q = &px[size_t(i) * spec.nchannels];
    EXPECT_NEAR(q[A], (q[AR] + q[AG] + q[AB]) / 3.0f, 1e-6f);
    alpha_sum += q[A];
    EXPECT_GE(q[R], 0.0f);
    EXPECT_GE(q[ER], 0.0f);
  }
  EXPECT_GT(alpha_sum, 0.0);
  auto h = OIIO::ImageInput::open(dir + "/h.exr");
  ASSERT_TRUE(h);
  EXPECT_EQ(h->spec().format, OIIO::TypeDesc::HALF);
  EXPECT_EQ(h->spec().get_string_attribute("compression"), "dwaa");
  // a half file cannot be merged (its sums are gone); the float one reads back
  EXPECT_THROW(read_piece(dir + "/h.exr"), Error);
  EXPECT_NO_THROW(read_piece(dir + "/f.exr"));
  // the PNG preview is the whole beauty (environment added back), like a render without layers
  Renderer plain_r(scene, quiet_options());
  RenderIdentity pid = render_identity(plain_r.settings());
  pid.scene_hash = "h";
  write_piece(dir + "/plain.png", piece_from_result(plain_r.render(), pid, "plain"), {});
  RgbImage a = read_image(dir + "/f.png"), b = read_image(dir + "/plain.png");
  ASSERT_EQ(a.rgb.size(), b.rgb.size());
  for (size_t i = 0; i < a.rgb.size(); ++i) EXPECT_NEAR(a.rgb[i], b.rgb[i], 0.01f) << i;  // 8-bit rounding
}

TEST(Aov, SceneFieldsAndTheirErrors) {
  const std::string dir = temp_dir("aov_scene");
  json s = slab("spectral", 4);
  s["film"]["alpha"] = false;
  s["film"]["aovs"] = {"environment", "variance"};
  s["film"]["half"] = true;
  s["film"]["compression"] = "piz";
  SceneDesc d = scene_from_json(s, dir);
  EXPECT_EQ(d.film.alpha, std::optional<bool>(false));
  EXPECT_EQ(d.film.aovs, uint32_t(ST_AOV_BIT(ENVIRONMENT) | ST_AOV_BIT(VARIANCE)));
  EXPECT_TRUE(d.film.half);
  EXPECT_EQ(d.film.compression, "piz");
  EXPECT_EQ(resolve_settings(d, quiet_options()).aovs, d.film.aovs);
  // alpha brings the environment layer (the transparent film's R, G, B leave it out)
  json a = slab("spectral", 4);
  a["film"]["aovs"] = {"alpha"};
  EXPECT_EQ(resolve_settings(scene_from_json(a, dir), quiet_options()).aovs,
            uint32_t(ST_AOV_BIT(ALPHA) | ST_AOV_BIT(ENVIRONMENT)));
  auto expect_error = [&](const std::function<void(json&)>& edit, const std::string& field, const std::string& word) {
    json e = slab("spectral", 4);
    edit(e);
    try {
      scene_from_json(e, dir);
      ADD_FAILURE() << "accepted " << e["film"].dump();
    } catch (const Error& err) {
      EXPECT_NE(std::string(err.what()).find(field), std::string::npos) << err.what();
      EXPECT_NE(std::string(err.what()).find(word), std::string::npos) << err.what();
    }
  };
  expect_error([](json& e) { e["film"]["aovs"] = {"normal"}; }, "/film/aovs/0", "unknown layer");
  expect_error([](json& e) { e["film"]["aovs"] = "alpha"; }, "/film/aovs", "array");
  expect_error([](json& e) { e["film"]["alpha"] = 1; }, "/film/alpha", "true or false");
  expect_error([](json& e) { e["film"]["compression"] = "jpeg"; }, "/film/compression", "dwaa");
  expect_error([](json& e) {
    e["film"]["alpha"] = false;
    e["film"]["aovs"] = {"alpha"};
  }, "/film/aovs", "film.alpha is false");
}

// The light passes (docs/aov.md): emission + direct + indirect (+ environment on an opaque film)
// is the beauty per pixel; the emission pass is what a render stopped at the first scattering
// event (max_depth 0) keeps besides the environment, and the direct pass what a render stopped
// at the second (max_depth 1) of a scene without emission keeps: the paths draw the same numbers
// up to there, so the comparisons hold per pixel to float rounding, not only in expectation.
TEST(Aov, PassesAddUpAndMatchDepthLimitedRenders) {
  const std::string dir = temp_dir("aov_passes");
  const uint32_t passes = ST_AOV_BIT(EMISSION) | ST_AOV_BIT(DIRECT) | ST_AOV_BIT(INDIRECT) | ST_AOV_BIT(ENVIRONMENT);
  // in both colour modes: spectral mode turns each pass into linear sRGB as it does the beauty
  for (const char* color : {"rgb", "spectral"})
  for (const char* tracker : {"delta-per-channel", "spectral-decomposition"})
    for (bool emissive : {true, false}) {
      SCOPED_TRACE(std::string(color) + " " + tracker + (emissive ? " emissive" : ""));
      json s = lumpy(dir, tracker, 4);
      s["render"]["color"] = color;
      if (emissive) s["media"][0]["emission"] = {{"radiance", {0.6, 0.4, 0.2}}};
      Renderer full_r(scene_from_json(s, dir), with_layers(passes));
      RenderResult full = full_r.render();
      ASSERT_EQ(full.aov_channels.size(), 12u);
      const size_t na = 12, npix = size_t(full.width) * full.height;
      // aov_sum_channels order: environment 0..2, emission 3..5, direct 6..8, indirect 9..11
      double direct_total = 0, indirect_total = 0, emission_total = 0;
      for (size_t i = 0; i < npix; ++i)
        for (int c = 0; c < 3; ++c) {
          const double* a = &full.aov_sum[i * na];
          const double parts = a[c] + a[3 + c] + a[6 + c] + a[9 + c];
          EXPECT_NEAR(parts, full.sum[i * 3 + c], 1e-5 * std::max(1.0, std::abs(full.sum[i * 3 + c])));
          emission_total += a[3 + c];
          direct_total += a[6 + c];
          indirect_total += a[9 + c];
        }
      EXPECT_GT(direct_total, 0.0);
      EXPECT_GT(indirect_total, 0.0);
      EXPECT_EQ(emission_total > 0.0, emissive);
      // the first scattering event ends the path: the beauty less the environment is the emission pass
      json s0 = s;
      s0["render"]["max_depth"] = emissive ? 0 : 1;
      RenderResult cut = Renderer(scene_from_json(s0, dir), with_layers(ST_AOV_BIT(ENVIRONMENT))).render();
      const size_t nc = cut.aov_channels.size();
      ASSERT_EQ(nc, 3u);
      for (size_t i = 0; i < npix; ++i)
        for (int c = 0; c < 3; ++c) {
          const double kept = cut.sum[i * 3 + c] - cut.aov_sum[i * nc + c];
          const double pass = full.aov_sum[i * na + (emissive ? 3 : 6) + c];
          EXPECT_NEAR(kept, pass, 1e-4 * std::max(1.0, std::abs(pass))) << "pixel " << i << " channel " << c;
        }
    }
}

TEST(Aov, PassesOnATransparentFilmAndThroughEveryLayerOfAnExr) {
  const std::string dir = temp_dir("aov_passes_exr");
  json s = lumpy(dir, "spectral", 4);
  s["media"][0]["emission"] = {{"radiance", {0.6, 0.4, 0.2}}};
  const uint32_t every = (1u << ST_AOV_COUNT) - 1;
  Renderer r(scene_from_json(s, dir), with_layers(every));
  RenderIdentity id = render_identity(r.settings());
  id.scene_hash = "h";
  RenderResult res = r.render();
  // alpha: R, G, B leave out the environment; the passes add up to them
  const size_t na = res.aov_channels.size(), npix = size_t(res.width) * res.height;
  auto at = [&](const std::string& n) {
    return size_t(std::find(res.aov_channels.begin(), res.aov_channels.end(), n) - res.aov_channels.begin());
  };
  for (size_t i = 0; i < npix; ++i)
    for (int c = 0; c < 3; ++c) {
      const std::string ch = std::string(".") + "RGB"[c];
      const double parts = res.aov_sum[i * na + at("emission" + ch)] + res.aov_sum[i * na + at("direct" + ch)] +
                           res.aov_sum[i * na + at("indirect" + ch)];
      EXPECT_NEAR(parts, res.sum[i * 3 + c], 1e-5 * std::max(1.0, std::abs(res.sum[i * 3 + c])));
    }
  FilmPiece p = piece_from_result(res, id, "p");
  write_piece(dir + "/all.exr", p, {});
  FilmPiece q = read_piece(dir + "/all.exr");
  EXPECT_EQ(q.id.aovs, every);
  ASSERT_EQ(q.aov_sum.size(), p.aov_sum.size());
  for (size_t i = 0; i < p.aov_sum.size(); ++i)
    EXPECT_NEAR(q.aov_sum[i], p.aov_sum[i], 1e-5 * std::max(1.0, std::abs(p.aov_sum[i]))) << res.aov_channels[i % na];
  auto in = OIIO::ImageInput::open(dir + "/all.exr");
  ASSERT_TRUE(in);
  EXPECT_EQ(in->spec().nchannels, 33);
  for (const char* n : {"emission.G", "direct.B", "indirect.R", "albedo.G", "depth.Z", "collision.fraction", "shadow.R",
                        "unshadowed.B"})
    EXPECT_GE(in->spec().channelindex(n), 0) << n;
}

// A scattering, absorbing chromatic box [-1, 1]^3 seen along z from z = -3: sigma_t = (1.5, 1.5, 2.25).
static json scattering_box(const std::string& tracker, int spp, double cam_height) {
  json s = base(16, 16, spp, tracker, cam_height);
  s["media"].push_back({{"type", "homogeneous"}, {"bounds", {{-1, -1, -1}, {1, 1, 1}}},
                        {"sigma_a", {0.5, 1.0, 2.0}}, {"sigma_s", {1.0, 0.5, 0.25}}});
  return s;
}

TEST(Aov, AlbedoIsTheBoxAlbedoExactlyWhereItIsSeenAndDepthTheMeanCollisionDistance) {
  const std::string dir = temp_dir("aov_albedo");
  const double albedo[3] = {1.0 / 1.5, 0.5 / 1.5, 0.25 / 2.25};
  const double sigma = (1.5 + 1.5 + 2.25) / 3.0, len = 2.0, q = std::exp(-sigma * len);
  // the collision distance of a flight of the channel-mean extinction, given that it collides:
  // 2 (to the box) + a truncated exponential on [0, len]
  const double expected_depth = 2.0 + 1.0 / sigma - len * q / (1.0 - q);
  for (const char* tracker : {"delta-per-channel", "spectral-decomposition"}) {
    SCOPED_TRACE(tracker);
    const uint32_t aux = ST_AOV_BIT(ALBEDO) | ST_AOV_BIT(DEPTH);
    // the frame (height 3) is wider than the box: its border rays meet nothing
    const SceneDesc scene = scene_from_json(scattering_box(tracker, 16, 3.0), dir);
    Renderer r(scene, with_layers(aux));
    EXPECT_TRUE(r.features() & ST_FEATURE_AOV);
    RenderResult res = r.render();
    ASSERT_EQ(res.aov_channels, (std::vector<std::string>{"albedo.R", "albedo.G", "albedo.B", "depth.Z", "collision.fraction"}));
    const size_t na = res.aov_channels.size();
    int seen = 0, missed = 0;
    std::vector<double> depths;
    for (int y = 0; y < res.height; ++y)
      for (int x = 0; x < res.width; ++x) {
        const size_t i = size_t(y) * res.width + x;
        const double* a = &res.aov_sum[i * na];
        const double px = -1.5 + 3.0 * (x + 0.5) / res.width, py = 1.5 - 3.0 * (y + 0.5) / res.height;
        const bool inside = std::abs(px) < 0.95 && std::abs(py) < 0.95, outside = std::abs(px) > 1.05 || std::abs(py) > 1.05;
        if (outside) {  // nothing on the ray: no collision, every layer 0 exactly
          ++missed;
          for (size_t c = 0; c < na; ++c) EXPECT_EQ(a[c], 0.0) << "pixel " << x << "," << y << " " << res.aov_channels[c];
        }
        if (!inside || a[4] <= 0) continue;
        ++seen;
        EXPECT_LE(a[4], 16.0);  // one flight per sample (delta-per-channel: the channel-0 path's)
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(a[c] / a[4], albedo[c], 1e-6) << "pixel " << x << "," << y;
        depths.push_back(a[3] / a[4]);
        EXPECT_GE(a[3] / a[4], 2.0 - 1e-5);
        EXPECT_LE(a[3] / a[4], 4.0 + 1e-5);
      }
    EXPECT_GT(seen, 90);  // 10 x 10 pixel centres inside the box's silhouette
    EXPECT_GT(missed, 90);
    // each seen pixel's depth is the mean of its collided samples' distances: unbiased given how
    // many collided, so the pixels' mean estimates expected_depth with their spread as its error
    Stats st = mean_se(depths);
    EXPECT_LT(std::abs(st.mean - expected_depth), 4 * st.se) << st.mean << " vs " << expected_depth << " se " << st.se;
    EXPECT_GT(std::abs(st.mean - 1.05 * expected_depth), 4 * st.se) << "the test cannot see a 5% error";
    // the beauty is the paths' own (the layers draw from their own stream): as without layers
    RenderResult plain = Renderer(scene, quiet_options()).render();
    for (size_t i = 0; i < plain.sum.size(); ++i)
      EXPECT_NEAR(res.sum[i], plain.sum[i], 1e-5 * std::max(1.0, std::abs(plain.sum[i]))) << i;
  }
}

TEST(Aov, AlbedoAndDepthLayersThroughExrShardsAndMerge) {
  const std::string dir = temp_dir("aov_albedo_merge");
  const SceneDesc scene = scene_from_json(lumpy(dir, "spectral", 8), dir);
  const uint32_t aovs = kAll | ST_AOV_BIT(ALBEDO) | ST_AOV_BIT(DEPTH) | ST_AOV_BIT(DIRECT);
  Renderer r(scene, with_layers(aovs));
  RenderIdentity id = render_identity(r.settings());
  id.scene_hash = "h";
  RenderResult all = r.render();
  FilmPiece full = piece_from_result(all, id, "full");
  // a heterogeneous, chromatic medium: albedo within [0, 1], depth within the camera ray's reach
  const std::vector<double> hits = layer(all, "collision.fraction");
  for (int c = 0; c < 3; ++c) {
    const std::vector<double> a = layer(all, std::string("albedo.") + "RGB"[c]);
    for (size_t i = 0; i < a.size(); ++i) {
      EXPECT_GE(a[i], 0.0);
      EXPECT_LE(a[i], hits[i] * (1 + 1e-6));
    }
  }
  EXPECT_GT(all.stats.lookups_alpha, 0u);  // the alpha estimate's and the albedo/depth flight's
  int some = 0;
  for (double h : hits) some += h > 0;
  EXPECT_GT(some, int(hits.size()) / 4);
  // EXR channels and their values: means over the collided samples, the collided fraction
  const std::string exr = dir + "/all.exr";
  write_piece(exr, full, {});
  auto in = OIIO::ImageInput::open(exr);
  ASSERT_TRUE(in);
  const OIIO::ImageSpec spec = in->spec();
  std::vector<float> px(hits.size() * size_t(spec.nchannels));
  ASSERT_TRUE(in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, px.data()));
  const int cz = spec.channelindex("depth.Z"), ca = spec.channelindex("collision.fraction"), cr = spec.channelindex("albedo.R");
  ASSERT_GE(cz, 0);
  ASSERT_GE(ca, 0);
  ASSERT_GE(cr, 0);
  const std::vector<double> dsum = layer(all, "depth.Z"), rsum = layer(all, "albedo.R");
  for (size_t i = 0; i < hits.size(); ++i) {
    EXPECT_NEAR(px[i * spec.nchannels + ca], hits[i], 1e-6);
    EXPECT_NEAR(px[i * spec.nchannels + cz], hits[i] > 0 ? dsum[i] / hits[i] : 0.0, 1e-5 * 3);
    EXPECT_NEAR(px[i * spec.nchannels + cr], hits[i] > 0 ? rsum[i] / hits[i] : 0.0, 1e-6);
  }
  // shards through EXR files merge to the full render's sums in every layer
  std::vector<FilmPiece> read;
  for (auto [b, e] : {std::pair{0, 3}, std::pair{3, 8}}) {
    const std::string f = dir + "/shard" + std::to_string(b) + ".exr";
    write_piece(f, piece_from_result(r.render(b, e - b), id, "shard"), {});
    read.push_back(read_piece(f));
    EXPECT_EQ(read.back().id.aovs, aovs);
  }
  FilmPiece m = merge_pieces(read);
  ASSERT_EQ(m.aov_sum.size(), full.aov_sum.size());
  for (size_t i = 0; i < full.aov_sum.size(); ++i)
    EXPECT_NEAR(m.aov_sum[i], full.aov_sum[i], 1e-4 * std::max(1.0, std::abs(full.aov_sum[i]))) << i;
}

// ---- spectral mode: the layers in linear sRGB ----

// The absorbing slab in spectral mode on a transparent film: the environment layer is the film of
// the sky's spectrum times exp(-2 sigma_a(lambda)), alpha is the film of D65 (1 - exp(-2 sigma_a))
// (1 minus what a white sky shows through), and R, G, B hold nothing; the rgb mode's alpha
// 1 - exp(-2 sigma_a,rgb) is told apart.
TEST(AovSpectral, SlabAlphaAndEnvironmentAreTheFilmOfTheTransmittance) {
  const std::string dir = temp_dir("aov_spectral_slab");
  const Rgb2SpecFit fit;
  const RgbSpectrum sa = rgb2spec_unbounded(fit, rgb2spec_srgb(), Rgb{0.5, 1.0, 2.0});
  const RgbSpectrum sky = rgb2spec_unbounded(fit, rgb2spec_srgb(), Rgb{0.5, 1.0, 2.0});
  const Rgb shown = film_of([&](double l) { return sky(l) * cie_d65(l) * std::exp(-2.0 * sa(l)); });
  const Rgb alpha = film_of([&](double l) { return cie_d65(l) * (1.0 - std::exp(-2.0 * sa(l))); });
  const char* a[3] = {"AR", "AG", "AB"};
  const char* e[3] = {"environment.R", "environment.G", "environment.B"};
  for (const char* tracker : {"delta-per-channel", "spectral-decomposition", "spectral-mis"}) {
    SCOPED_TRACE(tracker);
    json s = slab(tracker, 64);
    s["render"]["color"] = "spectral";
    RenderResult res = Renderer(scene_from_json(s, dir), with_layers(ST_AOV_BIT(ALPHA), 64)).render();
    double worst_rgb = 0;
    for (int c = 0; c < 3; ++c) {
      Stats sa_ = mean_se(layer(res, a[c]));
      EXPECT_NEAR(sa_.mean, alpha[c], 4.0 * sa_.se + 2e-4) << "alpha, channel " << c << " SE " << sa_.se;
      worst_rgb = std::max(worst_rgb, std::abs(sa_.mean - (1.0 - std::exp(-2.0 * (0.5 * (1 << c))))) / sa_.se);
      Stats se = mean_se(layer(res, e[c]));
      EXPECT_NEAR(se.mean, shown[c], 4.0 * se.se + 2e-4) << "environment, channel " << c << " SE " << se.se;
      for (size_t i = 0; i < size_t(res.width) * res.height; ++i) EXPECT_EQ(res.rgb[i * 3 + c], 0.0f);
    }
    EXPECT_GT(worst_rgb, 4.0) << "the rgb mode's alpha must be told apart";
  }
}

// The albedo layer in spectral mode is the film of the albedo spectrum sigma_s / sigma_t under D65
// (a reflectance), averaged over the samples whose camera ray collided; depth is unchanged.
TEST(AovSpectral, AlbedoLayerIsTheFilmOfTheAlbedoSpectrum) {
  const std::string dir = temp_dir("aov_spectral_albedo");
  const Rgb2SpecFit fit;
  const RgbSpectrum sa = rgb2spec_unbounded(fit, rgb2spec_srgb(), Rgb{0.5, 1.0, 2.0});
  const RgbSpectrum ss = rgb2spec_unbounded(fit, rgb2spec_srgb(), Rgb{1.0, 0.5, 0.25});
  const Rgb want = film_of([&](double l) { return cie_d65(l) * ss(l) / (sa(l) + ss(l)); });
  for (const char* tracker : {"delta-per-channel", "spectral-decomposition"}) {
    SCOPED_TRACE(tracker);
    json s = scattering_box(tracker, 32, 3.0);
    s["render"]["color"] = "spectral";
    RenderResult res = Renderer(scene_from_json(s, dir), with_layers(ST_AOV_BIT(ALBEDO) | ST_AOV_BIT(DEPTH))).render();
    ASSERT_EQ(res.aov_channels, (std::vector<std::string>{"albedo.R", "albedo.G", "albedo.B", "depth.Z", "collision.fraction"}));
    const size_t na = res.aov_channels.size();
    std::vector<double> albedo[3];
    for (size_t i = 0; i < size_t(res.width) * res.height; ++i) {
      const double* v = &res.aov_sum[i * na];
      if (v[4] <= 0) continue;  // no sample's camera ray collided
      for (int c = 0; c < 3; ++c) albedo[c].push_back(v[c] / v[4]);
      EXPECT_GE(v[3] / v[4], 2.0 - 1e-5);
      EXPECT_LE(v[3] / v[4], 4.0 + 1e-5);
    }
    ASSERT_GT(albedo[0].size(), 50u);
    for (int c = 0; c < 3; ++c) {
      Stats st = mean_se(albedo[c]);
      EXPECT_NEAR(st.mean, want[c], 4.0 * st.se + 2e-4) << "channel " << c << " SE " << st.se;
    }
  }
}
