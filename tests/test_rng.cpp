// test_rng.cpp: the kernels' random numbers (kernels/rng.h) on the device: Philox4x32-10 against
// Random123's known answers, the documented stream layout (draw k = word k mod 4 of the block
// k / 4), resumption at any draw, and chi-square tests of uniformity and of the independence of
// successive draws (inside a block, across block boundaries) and of neighbouring streams. Seeds
// are fixed, so each test is deterministic; a statistic fails at p < 1e-4 of its chi-square
// distribution, and a twin check on a deliberately flawed sequence shows that the same statistic
// does fail.
#include <cmath>
#include <cstdint>

#include "test_util.h"

using namespace spectrack;
using namespace st_test;
using nlohmann::json;

namespace {

// A renderer whose scene only provides the seed and the device (the probes need no medium).
json rng_scene(uint32_t seed) {
  return json{{"format", "spectrack-scene/1"},
              {"camera", {{"type", "orthographic"}, {"position", {0, 0, -3}}, {"look_at", {0, 0, 0}}, {"up", {0, 1, 0}}, {"height", 1.0}}},
              {"film", {{"width", 4}, {"height", 4}, {"spp", 1}}},
              {"render", {{"tracker", "spectral"}, {"seed", seed}}},
              {"lights", json::array()},
              {"media", json::array()}};
}

// Upper tail P(X >= x) of a chi-square variable with k degrees of freedom, by the Wilson-Hilferty
// cube-root normal approximation (relative error of the tail well under 10% at p = 1e-4 for the
// k >= 63 used here, ample for a pass/fail threshold).
double chi2_upper_tail(double x, double k) {
  const double a = 2.0 / (9.0 * k);
  const double z = (std::cbrt(x / k) - (1.0 - a)) / std::sqrt(a);
  return 0.5 * std::erfc(z / std::sqrt(2.0));
}

struct ChiSquare {
  double stat = 0, dof = 0, p = 1;
};

// Pearson's statistic of counts against equal cell probabilities.
ChiSquare chi_square(const std::vector<uint64_t>& counts) {
  uint64_t n = 0;
  for (uint64_t c : counts) n += c;
  const double e = double(n) / double(counts.size());
  ChiSquare r;
  for (uint64_t c : counts) r.stat += (double(c) - e) * (double(c) - e) / e;
  r.dof = double(counts.size() - 1);
  r.p = chi2_upper_tail(r.stat, r.dof);
  return r;
}

int bin_of(float u, int bins) { return std::min(bins - 1, int(double(u) * bins)); }

ChiSquare chi_square_1d(const std::vector<float>& u, int bins) {
  std::vector<uint64_t> c(size_t(bins), 0);
  for (float x : u) c[size_t(bin_of(x, bins))]++;
  return chi_square(c);
}

// Pairs (a[i], b[i]) over a bins x bins grid.
ChiSquare chi_square_2d(const std::vector<float>& a, const std::vector<float>& b, int bins) {
  std::vector<uint64_t> c(size_t(bins) * bins, 0);
  for (size_t i = 0; i < a.size(); ++i) c[size_t(bin_of(a[i], bins)) * bins + size_t(bin_of(b[i], bins))]++;
  return chi_square(c);
}

constexpr double kFail = 1e-4;   // p below this fails
constexpr int kStreams = 4096;   // streams per probe
constexpr uint32_t kDraws = 1024; // draws per stream (256 Philox blocks)

// Pairs (u_k, u_k+1) of every stream, for the k with k mod 4 = j (j = 3: across a block boundary).
void successive_pairs(const std::vector<float>& u, uint32_t draws, uint32_t j, std::vector<float>* a, std::vector<float>* b) {
  a->clear();
  b->clear();
  for (size_t s = 0; s < u.size() / draws; ++s)
    for (uint32_t k = j; k + 1 < draws; k += 4) {
      a->push_back(u[s * draws + k]);
      b->push_back(u[s * draws + k + 1]);
    }
}

}  // namespace

TEST(Rng, PhiloxMatchesRandom123KnownAnswers) {
  std::string dir = temp_dir("rng_kat");
  Renderer r(scene_from_json(rng_scene(1), dir), quiet_options());
  // Random123 1.14, tests/kat_vectors: "philox4x32 10" counter, key -> output
  auto out = Probe(r).philox({{{0u, 0u, 0u, 0u}, {0u, 0u}},
                              {{0xffffffffu, 0xffffffffu, 0xffffffffu, 0xffffffffu}, {0xffffffffu, 0xffffffffu}},
                              {{0x243f6a88u, 0x85a308d3u, 0x13198a2eu, 0x03707344u}, {0xa4093822u, 0x299f31d0u}}});
  const std::array<uint32_t, 4> expect[3] = {{0x6627e8d5u, 0xe169c58du, 0xbc57ac4cu, 0x9b00dbd8u},
                                             {0x408f276du, 0x41c83b0eu, 0xa20bc7c6u, 0x6d5451fdu},
                                             {0xd16cfe09u, 0x94fdccebu, 0x5001e420u, 0x24126ea1u}};
  for (int i = 0; i < 3; ++i)
    for (int w = 0; w < 4; ++w) EXPECT_EQ(out[i][w], expect[i][w]) << "vector " << i << " word " << w;
}

// Draw k of stream (pixel, sample, channel, stream) is word k mod 4 of
// Philox(counter = (pixel, sample*4 + channel, stream, k / 4), key = (seed, 0x5EC7AC4B)), as
// 24-bit uniforms in [0, 1).
TEST(Rng, DrawsAreTheFourWordsOfEachBlock) {
  std::string dir = temp_dir("rng_layout");
  const uint32_t seed = 12345;
  Renderer r(scene_from_json(rng_scene(seed), dir), quiet_options());
  Probe probe(r);
  const uint32_t draws = 64;
  const int n = 8;
  const std::array<uint32_t, 4> base{17u, 5u, 2u, 3u};  // pixel, sample, channel, stream
  auto u = probe.uniforms(base, 0, 0, draws, n);
  std::vector<std::pair<std::array<uint32_t, 4>, std::array<uint32_t, 2>>> in;
  for (int i = 0; i < n; ++i)
    for (uint32_t b = 0; b < draws / 4; ++b)
      in.push_back({{base[0] + uint32_t(i), base[1] * 4 + base[2], base[3], b}, {seed, 0x5EC7AC4Bu}});
  auto blocks = probe.philox(in);
  for (int i = 0; i < n; ++i)
    for (uint32_t k = 0; k < draws; ++k) {
      const float got = u[size_t(i) * draws + k];
      const float want = float(blocks[size_t(i) * (draws / 4) + k / 4][k % 4] >> 8) * (1.0f / 16777216.0f);
      ASSERT_EQ(got, want) << "stream " << i << " draw " << k;
      ASSERT_GE(got, 0.0f);
      ASSERT_LT(got, 1.0f);
      ASSERT_EQ(got * 16777216.0f, std::floor(got * 16777216.0f)) << "24-bit uniform";
    }
  // the twin: the old layout (one Philox call per draw, word 0, counter w = k) is not what we draw
  std::vector<std::pair<std::array<uint32_t, 4>, std::array<uint32_t, 2>>> old;
  for (uint32_t k = 0; k < draws; ++k) old.push_back({{base[0], base[1] * 4 + base[2], base[3], k}, {seed, 0x5EC7AC4Bu}});
  auto ob = probe.philox(old);
  int same = 0;
  for (uint32_t k = 0; k < draws; ++k) same += u[k] == float(ob[k][0] >> 8) * (1.0f / 16777216.0f);
  EXPECT_LE(same, 4) << "draws follow the old one-word-per-call layout";
}

// A generator rebuilt from its draw index (a path re-queued between launches, at any point of a
// block) continues the same stream, and a stream started at draw k is the tail of the full one.
TEST(Rng, ResumedStreamIsTheSameStream) {
  std::string dir = temp_dir("rng_resume");
  Renderer r(scene_from_json(rng_scene(99), dir), quiet_options());
  Probe probe(r);
  const uint32_t draws = 97;
  const int n = 256;
  auto full = probe.uniforms({3u, 1u, 0u, 0u}, 0, 0, draws, n);
  for (uint32_t every : {1u, 2u, 3u, 4u, 5u, 7u, 13u}) {
    auto resumed = probe.uniforms({3u, 1u, 0u, 0u}, 0, 0, draws, n, every);
    ASSERT_EQ(resumed, full) << "resume every " << every << " draws";
  }
  for (uint32_t first : {1u, 2u, 3u, 4u, 6u, 41u}) {
    auto tail = probe.uniforms({3u, 1u, 0u, 0u}, 0, first, draws - first, n);
    for (int i = 0; i < n; ++i)
      for (uint32_t k = 0; k + first < draws; ++k)
        ASSERT_EQ(tail[size_t(i) * (draws - first) + k], full[size_t(i) * draws + first + k])
            << "stream " << i << " started at draw " << first;
  }
}

// Uniformity: 1-D chi-square over 1000 bins of all draws and of each word position k mod 4.
TEST(Rng, ChiSquareUniformity) {
  std::string dir = temp_dir("rng_uniform");
  Renderer r(scene_from_json(rng_scene(2026), dir), quiet_options());
  auto u = Probe(r).uniforms({0u, 0u, 0u, 0u}, 0, 0, kDraws, kStreams);
  ChiSquare all = chi_square_1d(u, 1000);
  EXPECT_GT(all.p, kFail) << "chi2 " << all.stat << " dof " << all.dof;
  for (uint32_t j = 0; j < 4; ++j) {
    std::vector<float> w;
    for (size_t i = j; i < u.size(); i += 4) w.push_back(u[i]);
    ChiSquare c = chi_square_1d(w, 1000);
    EXPECT_GT(c.p, kFail) << "word " << j << ": chi2 " << c.stat << " dof " << c.dof;
  }
  // the twin: a slightly non-uniform sequence (u^1.02, the same draws) fails
  std::vector<float> bent(u.size());
  for (size_t i = 0; i < u.size(); ++i) bent[i] = std::pow(u[i], 1.02f);
  ChiSquare b = chi_square_1d(bent, 1000);
  EXPECT_LT(b.p, kFail) << "u^1.02 passes: chi2 " << b.stat;
}

// Independence of successive draws: pairs (u_k, u_k+1) over a 64 x 64 grid, for each position
// k mod 4 (3: the pair straddles two Philox blocks), and pairs (u_k, u_k+4) (the same word of
// successive blocks).
TEST(Rng, ChiSquareSuccessivePairs) {
  std::string dir = temp_dir("rng_pairs");
  Renderer r(scene_from_json(rng_scene(7), dir), quiet_options());
  auto u = Probe(r).uniforms({100u, 0u, 0u, 0u}, 0, 0, kDraws, kStreams);
  std::vector<float> a, b;
  for (uint32_t j = 0; j < 4; ++j) {
    successive_pairs(u, kDraws, j, &a, &b);
    ChiSquare c = chi_square_2d(a, b, 64);
    EXPECT_GT(c.p, kFail) << "pairs at k mod 4 = " << j << ": chi2 " << c.stat << " dof " << c.dof;
  }
  a.clear();
  b.clear();
  for (size_t s = 0; s < size_t(kStreams); ++s)
    for (uint32_t k = 0; k + 4 < kDraws; ++k) {
      a.push_back(u[s * kDraws + k]);
      b.push_back(u[s * kDraws + k + 4]);
    }
  ChiSquare c4 = chi_square_2d(a, b, 64);
  EXPECT_GT(c4.p, kFail) << "pairs (u_k, u_k+4): chi2 " << c4.stat;

  // the twins: a sequence whose odd draws repeat a neighbour with a small perturbation, and one
  // that reuses each block's first word (what a broken block cache would do), both fail
  std::vector<float> corr = u, reuse = u;
  for (size_t i = 1; i < corr.size(); i += 2) corr[i] = std::fmod(corr[i - 1] + 0.1f * u[i], 1.0f);
  for (size_t i = 0; i < reuse.size(); ++i) reuse[i] = u[i - i % 4];
  successive_pairs(corr, kDraws, 0, &a, &b);
  ChiSquare cc = chi_square_2d(a, b, 64);
  EXPECT_LT(cc.p, kFail) << "a correlated sequence passes: chi2 " << cc.stat;
  successive_pairs(reuse, kDraws, 1, &a, &b);
  ChiSquare cr = chi_square_2d(a, b, 64);
  EXPECT_LT(cr.p, kFail) << "a repeated word passes: chi2 " << cr.stat;
}

// Neighbouring streams: draw k of stream i against draw k of stream i + 1, where the streams are
// neighbouring pixels, samples, stream ids (a path and its first shadow ray, or successive shadow
// rays), and the three channels of one sample.
TEST(Rng, ChiSquareNeighbouringStreams) {
  std::string dir = temp_dir("rng_streams");
  Renderer r(scene_from_json(rng_scene(31337), dir), quiet_options());
  Probe probe(r);
  const uint32_t draws = 256;
  for (int axis : {0, 1, 3}) {
    auto u = probe.uniforms({5u, 9u, 0u, 0u}, axis, 0, draws, kStreams);
    std::vector<float> a, b;
    for (size_t s = 0; s + 1 < size_t(kStreams); ++s)
      for (uint32_t k = 0; k < draws; ++k) {
        a.push_back(u[s * draws + k]);
        b.push_back(u[(s + 1) * draws + k]);
      }
    ChiSquare c = chi_square_2d(a, b, 64);
    EXPECT_GT(c.p, kFail) << "neighbouring streams along axis " << axis << ": chi2 " << c.stat << " dof " << c.dof;
    if (axis == 0) {
      // the twin: the same stream twice (pairs (u_k, u_k)) fails
      ChiSquare same = chi_square_2d(a, a, 64);
      EXPECT_LT(same.p, kFail) << "identical streams pass";
    }
  }
  // channels 0, 1, 2 of many samples: pairs (channel c, channel c + 1) at each draw
  std::vector<float> a, b;
  for (uint32_t sample = 0; sample < 1024; ++sample) {
    auto u = probe.uniforms({77u, sample, 0u, 0u}, 2, 0, draws, 3);
    for (uint32_t c = 0; c + 1 < 3; ++c)
      for (uint32_t k = 0; k < draws; ++k) {
        a.push_back(u[c * draws + k]);
        b.push_back(u[(c + 1) * draws + k]);
      }
  }
  ChiSquare cc = chi_square_2d(a, b, 64);
  EXPECT_GT(cc.p, kFail) << "neighbouring channels: chi2 " << cc.stat << " dof " << cc.dof;
}
