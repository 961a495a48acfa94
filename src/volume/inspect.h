// inspect.h: what `spectrack info` reports about a volume file: every grid, whatever its type,
// read with the same structural checks as the loaders (volume.h). The world box is the active
// voxels' index box (voxel centres, inclusive) through the grid's own transform, as OpenVDB's
// Transform::indexToWorld(evalActiveVoxelBoundingBox()) gives it.
#pragma once
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "util/error.h"

namespace spectrack {

struct GridInfo {
  std::string name, type, cls;              // value type and class in the file's words
  bool empty = true;                        // no active values
  std::array<int, 3> index_min{0, 0, 0}, index_max{-1, -1, -1};  // active voxels, inclusive
  std::array<double, 3> world_min{0, 0, 0}, world_max{0, 0, 0};  // of the index box's corners
  std::array<double, 3> voxel_size{0, 0, 0};
  uint64_t active_voxels = 0;               // tiles counted by their volume
  bool has_range = false;                   // scalar grids; vector grids: the range of |v|
  double value_min = 0, value_max = 0;
  int64_t nanovdb_bytes = -1;               // size of the grid as a NanoVDB buffer; -1: not convertible
  std::string density_use;                  // "yes", or why the grid cannot be a medium's density
  std::string velocity_use;                 // vec3s grids: "yes" with the largest speed, or why not; else empty
};

// Every grid of a .vdb or .nvdb file. Throws spectrack::Error naming the file and the reason for
// a missing, unreadable, damaged or unknown file.
std::vector<GridInfo> inspect_volume(const std::string& file);

// A grid name or type from a file as text output prints it: control characters, backslash and
// quote escaped (\x1b, \\, \").
std::string printable_name(const std::string& s);

}  // namespace spectrack
