// grid_export: writes one float grid, exactly as the renderer loads it, as a dense array for a
// peer renderer (bench/mitsuba_side.py builds Mitsuba 3's gridvolume from it).
//
//   grid_export VOLUME.vdb|.nvdb GRID OUT_PREFIX
//
// Design: the grid goes through the renderer's own loader (load_float_grid: same grid choice,
// same validation), and every value is read at an integer index coordinate, i.e. at a voxel
// centre, through the host reference of the device lookup (sample_index_trilinear), so the
// export is the grid the kernels see. The dense box is the active index box grown by one voxel of
// background on each side: the trilinear density ramps to 0 exactly at those centres, so a
// cell-centred peer grid (values at the centres of N cells spanning the box) with clamp-to-edge
// filtering reproduces the renderer's density everywhere. OUT_PREFIX.f32 holds the values as
// little-endian float32, x fastest, then y, then z; OUT_PREFIX.json holds dims, the index of the
// first value (index_min - 1) and the file's index-to-world affine map.
#include <nlohmann/json.hpp>

#include <fstream>
#include <iostream>
#include <vector>

#include "volume/volume.h"

using namespace spectrack;

int main(int argc, char** argv) {
  if (argc != 4) {
    std::cerr << "usage: grid_export VOLUME GRID OUT_PREFIX\n";
    return 2;
  }
  try {
    GridData g = load_float_grid(argv[1], argv[2], -1, argv[1]);
    std::array<int, 3> lo{}, dims{};
    for (int a = 0; a < 3; ++a) {
      lo[a] = g.index_min[a] - 1;
      dims[a] = g.empty ? 1 : g.index_max[a] - g.index_min[a] + 3;
    }
    std::vector<float> v(size_t(dims[0]) * dims[1] * dims[2]);
    for (int k = 0; k < dims[2]; ++k)
      for (int j = 0; j < dims[1]; ++j)
        for (int i = 0; i < dims[0]; ++i)
          v[(size_t(k) * dims[1] + j) * dims[0] + i] = sample_index_trilinear(g, lo[0] + i, lo[1] + j, lo[2] + k);
    const std::string prefix = argv[3];
    std::ofstream f(prefix + ".f32", std::ios::binary);
    f.write(reinterpret_cast<const char*>(v.data()), std::streamsize(v.size() * sizeof(float)));
    nlohmann::json j;
    j["file"] = argv[1];
    j["grid"] = g.name;
    j["dims"] = dims;
    j["index_origin"] = lo;
    j["index_to_world"] = {std::vector<double>(g.index_to_world[0], g.index_to_world[0] + 4),
                           std::vector<double>(g.index_to_world[1], g.index_to_world[1] + 4),
                           std::vector<double>(g.index_to_world[2], g.index_to_world[2] + 4)};
    std::ofstream(prefix + ".json") << j.dump(2) << "\n";
    if (!f) throw Error("cannot write " + prefix + ".f32");
  } catch (const std::exception& e) {
    std::cerr << "grid_export: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
