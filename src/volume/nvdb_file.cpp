// nvdb_file.cpp: .nvdb files parsed as untrusted input (see volume.cpp's design note): each
// size is checked against the file length before anything is allocated, compressed chunks (BLOSC,
// ZIP) are decoded through OpenVDB's own codecs after checking their headers, and the decoded grid
// is validated (checksum, node pointers).
#include <openvdb/io/Compression.h>
#include <openvdb/openvdb.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>

#include <nanovdb/util/GridValidator.h>
#include <nanovdb/util/IO.h>

#include "util/host_memory.h"
#include "volume/nvdb_decode.h"
#include "volume/volume_detail.h"

namespace spectrack {
namespace volume_detail {

namespace fs = std::filesystem;

// ---- NanoVDB files ----------------------------------------------------------------------------

const char* nano_class_name(uint32_t c) {
  static const char* names[] = {"unknown",  "level set",  "fog volume", "staggered", "point index",
                                "point data", "topology", "voxel volume", "index"};
  return c < sizeof(names) / sizeof(names[0]) ? names[c] : "invalid class";
}

std::string nano_type_name(uint32_t t) {
  if (t < uint32_t(nanovdb::GridType::End)) return nanovdb::toStr(nanovdb::GridType(t));
  return "invalid type " + std::to_string(t);
}

// Lists the grids of a .nvdb file, checking every size against the file length.
std::vector<Entry> nvdb_entries(const std::string& file, const Fail& fail) {
  std::ifstream is(file, std::ios::binary);
  if (!is) fail(std::string("cannot open for reading: ") + std::strerror(errno));
  const uint64_t fsize = fs::file_size(file);
  std::vector<Entry> out;
  uint64_t pos = 0;
  while (pos < fsize) {
    nanovdb::io::Header h;
    if (fsize - pos < sizeof(h)) fail("truncated NanoVDB file (partial segment header at byte " + std::to_string(pos) + ")");
    is.seekg(std::streamoff(pos));
    is.read(reinterpret_cast<char*>(&h), sizeof(h));
    if (!is) fail("read error in NanoVDB segment header");
    if (h.magic != NANOVDB_MAGIC_NUMBER) {
      if (pos == 0) fail("not a NanoVDB file (bad magic number), or written by an incompatible NanoVDB version");
      fail("corrupt NanoVDB file: bad segment magic number at byte " + std::to_string(pos));
    }
    if (h.version.getMajor() != NANOVDB_MAJOR_VERSION_NUMBER) {
      // Version::c_str() returns a malloc'd buffer (leaked on every such file until fuzz_nvdb found it)
      const char* v = h.version.c_str();
      const std::string version(v);
      std::free(const_cast<char*>(v));
      fail(std::string("written by NanoVDB ") + version + ", but this build reads major version " +
           std::to_string(NANOVDB_MAJOR_VERSION_NUMBER) + " only");
    }
    if (h.gridCount == 0) fail("corrupt NanoVDB file: segment with no grids at byte " + std::to_string(pos));
    const uint16_t codec = uint16_t(h.codec);
    if (codec > uint16_t(nanovdb::io::Codec::BLOSC)) fail("corrupt NanoVDB file: unknown codec " + std::to_string(codec));
    pos += sizeof(h);
    std::vector<Entry> seg;
    for (uint32_t i = 0; i < h.gridCount; ++i) {
      nanovdb::io::MetaData m;
      if (fsize - pos < sizeof(m)) fail("truncated NanoVDB file (partial grid header)");
      is.read(reinterpret_cast<char*>(&m), sizeof(m));
      pos += sizeof(m);
      if (!is || m.nameSize == 0 || m.nameSize > fsize - pos || m.nameSize > (1u << 20)) {
        fail("corrupt NanoVDB file: bad grid header");
      }
      std::string name(m.nameSize, '\0');
      is.read(&name[0], m.nameSize);
      pos += m.nameSize;
      if (!is || name.back() != '\0') fail("corrupt NanoVDB file: unterminated grid name");
      Entry e;
      e.name = name.c_str();
      e.type = nano_type_name(uint32_t(m.gridType));
      e.cls = nano_class_name(uint32_t(m.gridClass));
      e.is_float = m.gridType == nanovdb::GridType::Float || nvdb_decodable(m.gridType);
      e.level_set = m.gridClass == nanovdb::GridClass::LevelSet;
      e.nv_grid_size = m.gridSize;
      e.nv_file_size = m.fileSize;
      e.nv_codec = codec;
      seg.push_back(e);
    }
    for (Entry& e : seg) {
      if (e.nv_file_size > fsize - pos) fail("truncated NanoVDB file (grid " + in_quotes(e.name) + " data runs past the end)");
      e.nv_offset = pos;
      pos += e.nv_file_size;
      out.push_back(e);
    }
  }
  if (out.empty()) fail("empty NanoVDB file (no grids)");
  return out;
}

// Checks a blosc chunk header (16 bytes: version, versionlz, flags, typesize, nbytes, blocksize,
// cbytes) so that blosc never reads past the chunk or writes past the expected size.
void check_blosc_header(const char* p, uint64_t csize, uint64_t expect, const Fail& fail) {
  // The size comes first: a chunk shorter than the header must not have its header read
  // (fuzz_nvdb: a 1-byte chunk read 12 bytes past it).
  if (csize < 16) fail("corrupt NanoVDB file: BLOSC chunk of " + std::to_string(csize) + " bytes, shorter than its header");
  uint32_t nbytes, cbytes;
  std::memcpy(&nbytes, p + 4, 4);
  std::memcpy(&cbytes, p + 12, 4);
  if (cbytes != csize || nbytes != expect) fail("corrupt NanoVDB file: bad BLOSC chunk header");
}

nanovdb::GridHandle<nanovdb::HostBuffer> nvdb_read_raw(const std::string& file, const Entry& e, const Fail& fail) {
  using nanovdb::io::Codec;
  const uint64_t gsize = e.nv_grid_size, csize = e.nv_file_size;
  if (gsize < sizeof(nanovdb::GridData) + sizeof(nanovdb::NanoTree<float>) || gsize % NANOVDB_DATA_ALIGNMENT) {
    fail("corrupt NanoVDB file: implausible grid size " + std::to_string(gsize));
  }
  // Neither codec expands data more than ~1000:1 on real grids; this bounds the allocation.
  const bool plausible = e.nv_codec == uint16_t(Codec::NONE) ? gsize == csize : gsize <= csize * 1024 + (1u << 20);
  if (!plausible) fail("corrupt NanoVDB file: grid size " + std::to_string(gsize) + " does not match its " +
                       std::to_string(csize) + " bytes on disk");
  if (const std::string s = host_memory_shortfall(double(gsize)); !s.empty())
    fail("grid " + in_quotes(e.name) + " " + s + "; free memory, or render on a machine with more");
  std::ifstream is(file, std::ios::binary);
  is.seekg(std::streamoff(e.nv_offset));
  nanovdb::HostBuffer buf = nanovdb::HostBuffer::create(gsize);
  char* dst = reinterpret_cast<char*>(buf.data());
  if (e.nv_codec == uint16_t(Codec::NONE)) {
    is.read(dst, std::streamsize(gsize));
    if (!is) fail("read error in NanoVDB grid data");
  } else {
    // Each chunk is a uint64 byte count and the payload, as OpenVDB's codecs expect; BLOSC
    // data comes in chunks of at most nanovdb::io::Internal::MAX_SIZE decoded bytes, ZIP in one.
    std::vector<char> chunk;
    uint64_t left = gsize, disk_left = csize;
    while (left > 0) {
      const uint64_t expect = e.nv_codec == uint16_t(Codec::BLOSC) ? std::min<uint64_t>(left, nanovdb::io::Internal::MAX_SIZE) : left;
      uint64_t n = 0;
      if (disk_left < 8) fail("truncated NanoVDB grid data");
      is.read(reinterpret_cast<char*>(&n), 8);
      disk_left -= 8;
      if (!is || n == 0 || n > disk_left) fail("corrupt NanoVDB file: bad compressed chunk size");
      chunk.resize(8 + n);
      std::memcpy(chunk.data(), &n, 8);
      is.read(chunk.data() + 8, std::streamsize(n));
      if (!is) fail("read error in NanoVDB grid data");
      disk_left -= n;
      std::istringstream cs(std::string(chunk.data(), chunk.size()));
      try {
        if (e.nv_codec == uint16_t(Codec::BLOSC)) {
          check_blosc_header(chunk.data() + 8, n, expect, fail);
          openvdb::io::bloscFromStream(cs, dst, expect);
        } else {
          openvdb::io::unzipFromStream(cs, dst, expect);
        }
      } catch (const openvdb::IoError& err) {
        const char* codec = e.nv_codec == uint16_t(Codec::BLOSC) ? "BLOSC" : "ZIP";
        fail(std::string(codec) + "-compressed NanoVDB grid, but this build cannot decode " + codec + " (" +
             err.what() + "); re-save the file uncompressed, e.g. nanovdb_convert without a codec");
      }
      dst += expect;
      left -= expect;
    }
  }
  auto* gd = reinterpret_cast<const nanovdb::GridData*>(buf.data());
  // GridHandle::grid() walks mGridIndex grids forward, so only index 0 is safe to look up.
  if (gd->mMagic != NANOVDB_MAGIC_NUMBER || gd->mGridSize != gsize || gd->mGridIndex != 0 || gd->mGridCount < 1) {
    fail("corrupt NanoVDB grid (bad grid header)");
  }
  // the grid's own version, as the file's segment header's: NanoVDB's validator would print another
  // through a buffer it never frees
  if (gd->mVersion.getMajor() != NANOVDB_MAJOR_VERSION_NUMBER) fail("corrupt NanoVDB grid (its version is not the file's)");
  return nanovdb::GridHandle<nanovdb::HostBuffer>(std::move(buf));
}

nanovdb::CoordBBox nvdb_index_bbox(const nanovdb::GridHandle<nanovdb::HostBuffer>& h, const Fail& fail) {
  const char* begin = reinterpret_cast<const char*>(h.data());
  const uint64_t size = h.size(), tree_at = sizeof(nanovdb::GridData);
  const uint64_t off = reinterpret_cast<const nanovdb::TreeData<3>*>(begin + tree_at)->mNodeOffset[3];
  // the root's first member is its bbox, whatever the grid's value type (NanoVDB's RootData)
  if (off >= size || tree_at + off > size - sizeof(nanovdb::CoordBBox) || (tree_at + off) % NANOVDB_DATA_ALIGNMENT)
    fail("corrupt NanoVDB grid (root outside the grid, or misaligned)");
  nanovdb::CoordBBox box;
  std::memcpy(static_cast<void*>(&box), begin + tree_at + off, sizeof box);
  return box;
}

nanovdb::GridHandle<nanovdb::HostBuffer> nvdb_read(const std::string& file, const Entry& e, const Fail& fail) {
  nanovdb::GridHandle<nanovdb::HostBuffer> handle = nvdb_read_raw(file, e, fail);
  if (nvdb_decodable(handle.gridMetaData()->gridType())) return nvdb_decode(handle, e, fail);
  const FloatGrid* g = handle.grid<float>();
  if (!g) fail("grid " + in_quotes(e.name) + " is not a float grid");
  check_tree_layout(*g, fail);
  return handle;
}

}  // namespace volume_detail
}  // namespace spectrack
