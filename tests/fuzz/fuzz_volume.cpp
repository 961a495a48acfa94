// fuzz_volume.cpp: libFuzzer harness for the VDB and NanoVDB loaders (src/volume), built twice by
// tests/fuzz/CMakeLists.txt: fuzz_vdb (FUZZ_VOLUME_EXT ".vdb") and fuzz_nvdb (".nvdb"). Seeds come
// from tests/fuzz/make_seeds.cpp (scripts/fuzz.sh writes them into its scratch folder).
//
// Contract under test: load_float_grid(), list_grids() and inspect_volume() on any bytes either succeed with a grid
// that obeys volume.h (a float fog grid, a consistent active box, finite non-negative values, a
// finite invertible transform) or throw spectrack::Error whose message names the file (for .vdb
// files, load_color_grid() too: three float grids with finite non-negative values); the
// majorant grid of an accepted grid bounds its host-side trilinear samples, and its adaptive hierarchy
// gives every block an entry. Anything else (another
// exception, a sanitizer report, a timeout, more than 2 GiB) is a finding.
#include <unistd.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>

#include "volume/inspect.h"
#include "volume/float_limits.h"
#include "volume/volume.h"
#include "fuzz_contract.h"

#ifndef FUZZ_VOLUME_EXT
#error "FUZZ_VOLUME_EXT must be \".vdb\" or \".nvdb\""
#endif

namespace {

namespace fs = std::filesystem;
std::string g_file;

void remove_file() {
  std::error_code ec;
  fs::remove(g_file, ec);
}

void check_error(const spectrack::Error& e) {
  const std::string msg = e.what();
  if (msg.find(g_file) == std::string::npos) finding("error message does not name the file: " + msg);
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  const char* tmp = std::getenv("TMPDIR");
  g_file = (fs::path(tmp && *tmp ? tmp : "/tmp") / ("spectrack-fuzz-" + std::to_string(getpid()) + FUZZ_VOLUME_EXT)).string();
  std::atexit(remove_file);
  std::cerr.setstate(std::ios::failbit);  // the loaders' warnings (duplicate grid names) are noise here
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  {
    std::ofstream f(g_file, std::ios::binary | std::ios::trunc);
    f.write(reinterpret_cast<const char*>(data), std::streamsize(size));
  }
  try {
    spectrack::list_grids(g_file);
  } catch (const spectrack::Error& e) {
    check_error(e);
  }
  try {
    spectrack::inspect_volume(g_file);  // `spectrack info`: every grid of the file
  } catch (const spectrack::Error& e) {
    check_error(e);
  }
  try {
    spectrack::GridData g = spectrack::load_float_grid(g_file, "density", -1, "");
    check(g.handle.grid<float>() != nullptr, "accepted grid is not a float grid");
    check(g.empty == (g.index_min[0] > g.index_max[0]), "empty flag disagrees with the active box");
    if (!g.empty) {
      for (int a = 0; a < 3; ++a) check(g.index_min[a] <= g.index_max[a], "active box inverted on one axis");
      check(std::isfinite(g.value_min) && std::isfinite(g.value_max), "value range not finite");
      check(g.value_min >= 0 && g.value_min <= g.value_max, "value range negative or inverted");
    }
    for (auto& row : g.index_to_world)
      for (double v : row) check(std::isfinite(v), "transform not finite");
    // the majorant grid is built for every accepted grid: it must bound the density and stay bounded
    const int64_t span = g.empty ? 0 : int64_t(g.index_max[0]) - g.index_min[0] + int64_t(g.index_max[1]) -
                                           g.index_min[1] + int64_t(g.index_max[2]) - g.index_min[2];
    if (span < 3 * 4096) {
      try {
        // the renderer's automatic cell (at least 8 voxels here, to keep small grids quick): at most
        // about 2^22 cells, whatever the box; an explicit --majorant-cell may ask for up to 2^27
        const int cell = std::max(8, spectrack::auto_majorant_cell(g));
        spectrack::MajorantGrid mg = spectrack::build_majorant_grid(g, cell);
        check(mg.dmax.size() == mg.dmin.size(), "majorant arrays differ in size");
        if (!g.empty) {
          const double x = g.index_min[0] + 0.37, y = g.index_min[1] + 0.61, z = g.index_min[2] + 0.13;
          const float v = spectrack::sample_index_trilinear(g, x, y, z);
          const int cx = int(std::floor((x - mg.origin[0]) / mg.cell)), cy = int(std::floor((y - mg.origin[1]) / mg.cell)),
                    cz = int(std::floor((z - mg.origin[2]) / mg.cell));
          if (cx >= 0 && cy >= 0 && cz >= 0 && cx < mg.dims[0] && cy < mg.dims[1] && cz < mg.dims[2]) {
            const size_t c = (size_t(cz) * mg.dims[1] + cy) * mg.dims[0] + cx;
            check(v <= mg.dmax[c] && v >= mg.dmin[c], "majorant cell does not bound a trilinear sample");
          }
        }
        // the adaptive hierarchy over it: every block has an entry, every refined block its groups
        spectrack::MajorantCostModel cost;
        cost.decompose = true;
        spectrack::MajorantHierarchy h = spectrack::build_majorant_hierarchy(mg, 4, cost);
        const size_t nb = size_t(h.block_dims[0]) * h.block_dims[1] * h.block_dims[2];
        check(h.blocks.size() == nb, "hierarchy: a block without an entry");
        size_t per_level = 0;
        for (size_t n : h.blocks_per_level) per_level += n;
        check(per_level == nb && h.blocks_empty + h.blocks_whole + h.blocks_refined == nb, "hierarchy: blocks miscounted");
      } catch (const spectrack::Error&) {
        // a box too large for a majorant grid is refused with an Error, which is the contract
      }
    }
  } catch (const spectrack::Error& e) {
    check_error(e);
  }
  if (std::string(FUZZ_VOLUME_EXT) == ".vdb") {
    try {
      std::array<spectrack::GridData, 3> c = spectrack::load_color_grid(g_file, "Cd", "");
      for (const spectrack::GridData& g : c) {
        check(g.handle.grid<float>() != nullptr, "accepted colour component is not a float grid");
        check(std::isfinite(g.value_min) && std::isfinite(g.value_max), "colour range not finite");
        check(g.value_min >= 0 && g.value_min <= g.value_max, "colour range negative or inverted");
        for (auto& row : g.index_to_world)
          for (double v : row) check(std::isfinite(v), "colour transform not finite");
      }
    } catch (const spectrack::Error& e) {
      check_error(e);
    }
  }
  return 0;
}
