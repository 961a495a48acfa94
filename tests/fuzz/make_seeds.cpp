// make_seeds.cpp: writes the seed corpora of the file-format fuzzers (fuzz_vdb, fuzz_nvdb,
// fuzz_image) with the project's own code and libraries, so that no third-party file is
// committed: scripts/fuzz.sh runs it into its scratch folder before fuzzing.
//   make_seeds OUT_DIR  ->  OUT_DIR/vdb/*.vdb, OUT_DIR/nvdb/*.nvdb, OUT_DIR/image/*
// The files are tiny (a few voxels, 4x2 pixels) so that each mutation runs in microseconds.
#include <openvdb/io/Compression.h>
#include <openvdb/openvdb.h>

#include <nanovdb/util/GridHandle.h>
#include <nanovdb/util/IO.h>
#include <nanovdb/util/OpenToNanoVDB.h>

#include <OpenImageIO/imageio.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;

namespace {

openvdb::FloatGrid::Ptr fog(const std::string& name, int n, float value, double voxel) {
  auto g = openvdb::FloatGrid::create(0.0f);
  g->setName(name);
  g->setGridClass(openvdb::GRID_FOG_VOLUME);
  g->setTransform(openvdb::math::Transform::createLinearTransform(voxel));
  auto acc = g->getAccessor();
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) acc.setValue(openvdb::Coord(i, j, k), value * float(1 + i + j + k));
  return g;
}

void write_vdb(const fs::path& p, const openvdb::GridPtrVec& grids, uint32_t compression) {
  openvdb::io::File f(p.string());
  f.setCompression(compression);
  f.write(grids);
  f.close();
}

// One-grid .nvdb, encoded as NanoVDB's writer does (a uint64 size, then the compressed bytes).
void write_nvdb(const fs::path& p, const nanovdb::GridHandle<nanovdb::HostBuffer>& h, nanovdb::io::Codec codec) {
  std::ostringstream payload;
  const char* bytes = reinterpret_cast<const char*>(h.data());
  if (codec == nanovdb::io::Codec::ZIP) openvdb::io::zipToStream(payload, bytes, h.size());
  else if (codec == nanovdb::io::Codec::BLOSC) openvdb::io::bloscToStream(payload, bytes, sizeof(float), h.size() / sizeof(float));
  else payload.write(bytes, std::streamsize(h.size()));
  nanovdb::io::Header header(codec);
  header.gridCount = 1;
  nanovdb::io::GridMetaData meta(h.size(), codec, *h.grid<float>());
  meta.fileSize = payload.str().size();
  std::ofstream os(p, std::ios::binary);
  os.write(reinterpret_cast<const char*>(&header), sizeof(header));
  meta.write(os);
  os << payload.str();
}

// One-grid .nvdb of any value type, uncompressed, by NanoVDB's own writer.
void write_any_nvdb(const fs::path& p, const nanovdb::GridHandle<nanovdb::HostBuffer>& h) {
  nanovdb::io::writeGrid(p.string(), h, nanovdb::io::Codec::NONE);
}

void write_img(const fs::path& p, int w, int h, int nc, OIIO::TypeDesc type, int x0 = 0, int depth = 1) {
  auto out = OIIO::ImageOutput::create(p.string());
  if (!out) throw std::runtime_error("no writer for " + p.string());
  OIIO::ImageSpec spec(w, h, nc, type);
  spec.depth = depth;
  if (x0) spec.x = x0, spec.full_width = w + x0;
  spec.attribute("spectrack:spp", 4);
  spec.attribute("spectrack:scene_hash", "0123");
  std::vector<float> px(size_t(w) * h * nc * depth);
  for (size_t i = 0; i < px.size(); ++i) px[i] = 0.25f * float(i % 5);
  if (!out->open(p.string(), spec) || !out->write_image(OIIO::TypeDesc::FLOAT, px.data()) || !out->close())
    throw std::runtime_error("cannot write " + p.string() + ": " + out->geterror());
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: make_seeds OUT_DIR\n");
    return 2;
  }
  const fs::path out = argv[1];
  for (const char* d : {"vdb", "nvdb", "image"}) fs::create_directories(out / d);
  openvdb::initialize();
  try {
    write_vdb(out / "vdb" / "fog.vdb", {fog("density", 3, 0.5f, 0.1)}, openvdb::io::COMPRESS_NONE);
    write_vdb(out / "vdb" / "fog_zip.vdb", {fog("density", 3, 0.5f, 0.1)}, openvdb::io::COMPRESS_ZIP | openvdb::io::COMPRESS_ACTIVE_MASK);
    write_vdb(out / "vdb" / "fog_blosc.vdb", {fog("density", 2, 1.0f, 2.0)}, openvdb::io::COMPRESS_BLOSC);
    write_vdb(out / "vdb" / "two_grids.vdb", {fog("density", 2, 0.5f, 1.0), fog("heat", 2, 2.0f, 1.0)}, openvdb::io::COMPRESS_ZIP);
    {
      auto cd = openvdb::Vec3SGrid::create(openvdb::Vec3s(0.0f));  // a colour grid beside the density
      cd->setName("Cd");
      cd->setTransform(openvdb::math::Transform::createLinearTransform(0.1));
      auto acc = cd->getAccessor();
      for (int i = 0; i < 3; ++i) acc.setValue(openvdb::Coord(i, 1, 2), openvdb::Vec3s(0.2f * float(i), 0.5f, 1.0f));
      write_vdb(out / "vdb" / "color.vdb", {fog("density", 3, 0.5f, 0.1), cd}, openvdb::io::COMPRESS_ZIP);
    }
    {
      auto d = openvdb::DoubleGrid::create(0.0);  // a double density grid, read as float
      d->setName("density");
      d->setGridClass(openvdb::GRID_FOG_VOLUME);
      auto acc = d->getAccessor();
      for (int i = 0; i < 4; ++i) acc.setValue(openvdb::Coord(i, 2 - i, 1), 0.25 * double(1 + i));
      write_vdb(out / "vdb" / "double.vdb", {d}, openvdb::io::COMPRESS_ZIP);
    }
    write_vdb(out / "vdb" / "empty.vdb", {openvdb::FloatGrid::create(0.0f)}, openvdb::io::COMPRESS_NONE);
    auto ls = fog("density", 2, -1.0f, 1.0);  // negative values in a level-set-classed grid
    ls->setGridClass(openvdb::GRID_LEVEL_SET);
    write_vdb(out / "vdb" / "level_set.vdb", {ls}, openvdb::io::COMPRESS_ZIP);
    auto h = nanovdb::openToNanoVDB(*fog("density", 3, 0.5f, 0.1));
    write_nvdb(out / "nvdb" / "fog.nvdb", h, nanovdb::io::Codec::NONE);
    write_nvdb(out / "nvdb" / "fog_zip.nvdb", h, nanovdb::io::Codec::ZIP);
    write_nvdb(out / "nvdb" / "fog_blosc.nvdb", h, nanovdb::io::Codec::BLOSC);
    write_nvdb(out / "nvdb" / "empty.nvdb", nanovdb::openToNanoVDB(*openvdb::FloatGrid::create(0.0f)), nanovdb::io::Codec::NONE);
    {  // double and quantized grids, decoded into float ones (src/volume/nvdb_decode.cpp); an active tile
      auto g = fog("density", 9, 0.1f, 0.1);
      g->tree().addTile(1, openvdb::Coord(64, 0, 0), 0.75f, true);
      using nanovdb::ChecksumMode, nanovdb::StatsMode, nanovdb::HostBuffer;
      write_any_nvdb(out / "nvdb" / "fp4.nvdb", nanovdb::openToNanoVDB<HostBuffer, openvdb::FloatTree, nanovdb::Fp4>(*g));
      write_any_nvdb(out / "nvdb" / "fp8.nvdb", nanovdb::openToNanoVDB<HostBuffer, openvdb::FloatTree, nanovdb::Fp8>(*g));
      write_any_nvdb(out / "nvdb" / "fp16_full.nvdb",
                     nanovdb::openToNanoVDB<HostBuffer, openvdb::FloatTree, nanovdb::Fp16>(*g, StatsMode::Default, ChecksumMode::Full));
      write_any_nvdb(out / "nvdb" / "fpn.nvdb", nanovdb::openToNanoVDB<HostBuffer, openvdb::FloatTree, nanovdb::FpN>(*g));
      write_any_nvdb(out / "nvdb" / "fpn_unchecked.nvdb",
                     nanovdb::openToNanoVDB<HostBuffer, openvdb::FloatTree, nanovdb::FpN>(*g, StatsMode::Default, ChecksumMode::Disable));
      openvdb::DoubleGrid d(std::make_shared<openvdb::DoubleTree>(g->tree()));
      d.setName("density");
      d.setGridClass(openvdb::GRID_FOG_VOLUME);
      write_any_nvdb(out / "nvdb" / "double.nvdb", nanovdb::openToNanoVDB<HostBuffer, openvdb::DoubleTree, double>(d));
    }
    write_img(out / "image" / "rgb.exr", 4, 2, 3, OIIO::TypeDesc::FLOAT);
    write_img(out / "image" / "rgba_half.exr", 4, 2, 4, OIIO::TypeDesc::HALF);
    write_img(out / "image" / "gray.exr", 4, 2, 1, OIIO::TypeDesc::FLOAT);
    write_img(out / "image" / "tile.exr", 2, 2, 3, OIIO::TypeDesc::FLOAT, 2);
    write_img(out / "image" / "rgb.png", 4, 2, 3, OIIO::TypeDesc::UINT8);
    write_img(out / "image" / "gray_alpha.png", 4, 2, 2, OIIO::TypeDesc::UINT8);
    write_img(out / "image" / "rgb.hdr", 4, 2, 3, OIIO::TypeDesc::FLOAT);
    write_img(out / "image" / "rgb.tif", 4, 2, 3, OIIO::TypeDesc::UINT16);
    // fuzz_image's finding: a header that claims far more pixels than its file holds (refused by size)
    std::ofstream(out / "image" / "wide_claim.hdr", std::ios::binary)
        << "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 5 +X 33343333\n" << std::string(16, '3');
  } catch (const std::exception& e) {
    std::fprintf(stderr, "make_seeds: %s\n", e.what());
    return 1;
  }
  return 0;
}
