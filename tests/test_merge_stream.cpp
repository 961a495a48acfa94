// test_merge_stream.cpp: `spectrack merge` streams its inputs a band of rows at a time
// (film/merge_files.h) and must give the image a merge of whole images gives, bit for bit; it
// refuses inputs whose sample counts disagree with their sample ranges, and an input found
// damaged part-way leaves no output behind.
//
// Design: the pieces are made in memory (random sums, every film layer, tiles and shards of one
// 24x16 film) and written with write_piece, so the comparison covers every channel's encoding
// and decoding without rendering. The whole-image merge is read_piece + merge_pieces +
// write_piece, as spectrack merged before it streamed.
#include <OpenImageIO/imagebuf.h>

#include <random>

#include "cli_util.h"
#include "film/film.h"
#include "film/merge_files.h"

namespace {

using namespace st_cli;
using spectrack::FilmPiece;

constexpr int kW = 24, kH = 16;

FilmPiece random_piece(int x0, int x1, int y0, int y1, int64_t s0, int64_t s1, uint32_t aovs, unsigned seed) {
  FilmPiece p;
  p.source = "test";
  p.id.full_width = kW;
  p.id.full_height = kH;
  p.id.scene_hash = "0123456789abcdef0123456789abcdef01234567";
  p.id.tracker = "spectral";
  p.id.scheme = "max";
  p.id.version = SPECTRACK_VERSION;
  p.id.aovs = aovs;
  p.x0 = x0, p.y0 = y0, p.width = x1 - x0, p.height = y1 - y0;
  p.ranges = {{s0, s1}};
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 3.0);
  const size_t npix = size_t(p.width) * p.height, na = spectrack::aov_sum_channels(aovs).size();
  for (size_t i = 0; i < npix * 3; ++i) p.sum.push_back(u(rng) * double(s1 - s0));
  for (size_t i = 0; i < npix * na; ++i) p.aov_sum.push_back(u(rng) * u(rng) * double(s1 - s0));
  return p;
}

// Tiles of samples 0:4 and a whole-film shard of samples 4:7, written to dir.
std::vector<std::string> write_pieces(const std::string& dir, uint32_t aovs) {
  const std::vector<FilmPiece> pieces = {random_piece(0, 10, 0, 7, 0, 4, aovs, 1), random_piece(10, 24, 0, 7, 0, 4, aovs, 2),
                                         random_piece(0, 24, 7, 16, 0, 4, aovs, 3), random_piece(0, 24, 0, 16, 4, 7, aovs, 4)};
  std::vector<std::string> files;
  for (size_t k = 0; k < pieces.size(); ++k) {
    files.push_back(dir + "/piece" + std::to_string(k) + ".exr");
    spectrack::write_piece(files.back(), pieces[k], {{"device", std::string("test")}});
  }
  return files;
}

std::string file_bytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
}

void check_streamed_equals_whole(uint32_t aovs) {
  const std::string dir = test_dir();
  const std::vector<std::string> files = write_pieces(dir, aovs);
  std::vector<FilmPiece> whole;
  std::vector<spectrack::MergeInput> inputs;
  std::vector<FilmPiece> headers;
  for (auto& f : files) {
    whole.push_back(spectrack::read_piece(f));
    inputs.push_back(spectrack::read_merge_header(f));
    headers.push_back(inputs.back().piece);
  }
  const spectrack::Metadata meta = {{"scene", std::string("s.json")}};
  spectrack::write_piece(dir + "/whole.exr", spectrack::merge_pieces(whole), meta);
  spectrack::write_piece(dir + "/whole.png", spectrack::merge_pieces(whole), meta);
  const FilmPiece layout = spectrack::plan_merge(headers);
  // bands of 1 row, of a few rows (not a divisor of 16, crossing the tiles' edges), and whole
  for (size_t band_bytes : {size_t(1), size_t(kW) * 3 * 200, spectrack::kMergeBandBytes}) {
    const std::string out = dir + "/streamed.exr", png = dir + "/streamed.png";
    spectrack::write_merged(inputs, layout, out, png, meta, {}, band_bytes);
    EXPECT_EQ(file_bytes(png), file_bytes(dir + "/whole.png")) << "band bytes " << band_bytes;
    const spectrack::RgbImage a = spectrack::read_image(out, spectrack::ImageUse::kFilmPiece);
    const spectrack::RgbImage b = spectrack::read_image(dir + "/whole.exr", spectrack::ImageUse::kFilmPiece);
    EXPECT_EQ(a.rgb, b.rgb) << "band bytes " << band_bytes;
    EXPECT_EQ(a.extra, b.extra);
    EXPECT_EQ(a.extra_names, b.extra_names);
    EXPECT_EQ(a.meta, b.meta);  // the spectrack:* metadata (the files differ in their DateTime only)
  }
}

TEST(MergeStream, BandsGiveTheWholeMergeBitForBitBeauty) { check_streamed_equals_whole(0); }
TEST(MergeStream, BandsGiveTheWholeMergeBitForBitEveryLayer) {
  check_streamed_equals_whole((1u << ST_AOV_COUNT) - 1);
}

// A merge input converted to a tiled EXR (spectrack writes scanlines; other tools may tile) is
// read in rows of tiles and merges to the same image.
TEST(MergeStream, TiledInputsMergeToTheSameImage) {
  const std::string dir = test_dir();
  const std::vector<std::string> files = write_pieces(dir, 0);
  std::vector<FilmPiece> whole;
  for (auto& f : files) whole.push_back(spectrack::read_piece(f));
  OIIO::ImageBuf buf(files[3]);
  ASSERT_TRUE(buf.read(0, 0, true, OIIO::TypeDesc::FLOAT)) << buf.geterror();
  buf.set_write_tiles(8, 3);  // 3 rows: tile rows straddle every band of rows
  ASSERT_TRUE(buf.write(dir + "/tiled.exr")) << buf.geterror();
  std::vector<spectrack::MergeInput> inputs;
  std::vector<FilmPiece> headers;
  for (auto& f : {files[0], files[1], files[2], dir + "/tiled.exr"}) {
    inputs.push_back(spectrack::read_merge_header(f));
    headers.push_back(inputs.back().piece);
  }
  spectrack::write_piece(dir + "/whole.exr", spectrack::merge_pieces(whole), {});
  for (size_t band_bytes : {size_t(1), size_t(kW) * 3 * 200}) {
    spectrack::write_merged(inputs, spectrack::plan_merge(headers), dir + "/streamed.exr", "", {}, {}, band_bytes);
    EXPECT_EQ(spectrack::read_image(dir + "/streamed.exr", spectrack::ImageUse::kFilmPiece).rgb,
              spectrack::read_image(dir + "/whole.exr", spectrack::ImageUse::kFilmPiece).rgb)
        << "band bytes " << band_bytes;
  }
}

// `path` rewritten with spectrack:`key` set to `value` (or removed where value is empty).
void set_attribute(const std::string& path, const std::string& key, const std::string& value, bool as_int) {
  OIIO::ImageBuf buf(path);
  ASSERT_TRUE(buf.read(0, 0, true, OIIO::TypeDesc::FLOAT)) << buf.geterror();
  if (value.empty()) buf.specmod().erase_attribute("spectrack:" + key);
  else if (as_int) buf.specmod().attribute("spectrack:" + key, std::stoi(value));
  else buf.specmod().attribute("spectrack:" + key, value);
  const std::string tmp = path + ".tmp.exr";
  ASSERT_TRUE(buf.write(tmp)) << buf.geterror();
  fs::rename(tmp, path);
}

TEST(MergeStream, SampleCountsThatDisagreeWithTheRangesAreRefused) {
  const std::string dir = test_dir();
  std::vector<std::string> files = write_pieces(dir, 0);
  ASSERT_EQ(run({"merge", dir + "/ok.exr", files[0], files[1], files[2], files[3]}).code, 0);
  struct Case {
    std::string key, value;
    bool as_int;
    std::vector<std::string> words;
  };
  const std::vector<Case> cases = {{"spp", "5", true, {"spectrack:spp 5", "0:4"}},
                                   {"spp", "4", false, {}},  // text "4": agrees, accepted
                                   {"spp_begin", "1", true, {"spp_begin 1", "0:4"}},
                                   {"spp_end", "", true, {"spp_end (missing)", "0:4"}},
                                   {"spp_ranges", "0:3", false, {"spectrack:spp 4", "0:3"}},
                                   {"spp", "x", false, {"spectrack:spp 'x' is not an integer"}}};
  for (const Case& c : cases) {
    files = write_pieces(dir, 0);
    set_attribute(files[1], c.key, c.value, c.as_int);
    fs::remove(dir + "/out.exr");
    Proc p = run({"merge", dir + "/out.exr", files[0], files[1], files[2], files[3]});
    if (c.words.empty()) {
      EXPECT_EQ(p.code, 0) << p.describe();
      continue;
    }
    expect_error_exit(p);
    EXPECT_THAT(p.out, HasSubstr("piece1.exr")) << p.describe();
    for (auto& w : c.words) EXPECT_THAT(p.out, HasSubstr(w)) << c.key << "\n" << p.describe();
    EXPECT_FALSE(fs::exists(dir + "/out.exr")) << p.describe();
  }
}

TEST(MergeStream, DamageFoundPartWayLeavesNoOutput) {
  const std::string dir = test_dir();
  const std::vector<std::string> files = write_pieces(dir, 0);
  // a NaN in the last row of the shard: found after most rows were merged and written
  FilmPiece bad = spectrack::read_piece(files[3]);
  bad.sum[bad.sum.size() - 2] = std::nan("");
  spectrack::write_piece(files[3], bad, {});
  std::ofstream(dir + "/out.exr") << "an older file";
  Proc p = run({"merge", dir + "/out.exr", files[0], files[1], files[2], files[3], "--preview", dir + "/out.png"});
  expect_error_exit(p);
  EXPECT_THAT(p.out, HasSubstr("piece3.exr")) << p.describe();
  EXPECT_THAT(p.out, HasSubstr("non-finite")) << p.describe();
  EXPECT_EQ(file_bytes(dir + "/out.exr"), "an older file") << "the older output was replaced";
  EXPECT_FALSE(fs::exists(dir + "/out.png"));
  for (auto& e : fs::directory_iterator(dir))
    EXPECT_EQ(e.path().string().find("partial"), std::string::npos) << "left behind: " << e.path();
}

}  // namespace
