// scene_pack.h: a scene description turned into what the kernels read.
//
// Design: packing is pure host work with no OpenCL in it: media (world-to-index matrices,
// coefficients times density_scale, NanoVDB grids as 32-bit words, majorant/minorant grids with
// their adaptive hierarchy), lights (environment maps with their sampling CDFs), the camera
// and the render constants go into one plain PackedScene. The renderer uploads it as it is;
// tests and tools can inspect it without a device. features() is the st_feature mask the
// specialised kernels are compiled for (kernels/features.h).
#pragma once
#include <cstdint>
#include <optional>
#include <vector>

#include "integrator/settings.h"
#include "scene/scene.h"

namespace spectrack {

struct PackedScene {
  st_scene st{};                    // the __constant block (batches_in_flight is set per render)
  std::vector<uint32_t> grid_words;  // NanoVDB grids, 32-bit words (never empty)
  std::vector<float> maj_cells;      // (dmax, dmin) pairs of every majorant grid, hierarchy block entries (never empty)
  std::vector<float> env_data;       // environment texels and CDFs (never empty)
  uint32_t features = 0;             // st_feature mask of the scene and tracker
  std::vector<MajorantInfo> majorants;  // one per VDB medium, in scene order
};

struct PackOptions {
  int majorant_cell = 0;   // voxels per fine majorant-cell edge; 0: automatic (auto_majorant_cell)
  int majorant_block = kDefaultMajorantBlock;  // fine cells per block edge of the adaptive hierarchy; 0 or 1: one level
  int iteration_budget = kDefaultIterationBudget;
  std::optional<double> majorant_step_cost;  // the hierarchy's cost model: one DDA step, in density lookups; else automatic
};

// The packer's options of a render's settings.
inline PackOptions pack_options(const RenderSettings& s) {
  return {s.majorant_cell, s.majorant_block, s.iteration_budget, s.majorant_step_cost};
}

// Loads every grid and map the scene references and packs it; throws Error naming the file and
// field for bad data (singular transforms, unreadable grids and maps, negative texels, > 4 GiB).
PackedScene pack_scene(const SceneDesc& scene, const RenderSettings& settings, const PackOptions& options);

}  // namespace spectrack
