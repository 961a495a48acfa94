// velocity_grid.h: a medium's velocity grid for motion blur (docs/scene-format.md, "Motion blur"):
// a vec3s grid of an OpenVDB file read as one NanoVDB Vec3f grid on the device (kernels/medium.h
// medium_lookup_index: one tree walk for the three components), with the bounds of its values
// that the majorant margin needs.
//
// Design: the velocity is read once, at load, into what the kernels use: outliers (voxels whose
// speed exceeds the threshold) are zeroed there, so the interpolated velocity and the bounds
// computed here see the same values. A staggered (MAC) grid, OpenVDB's grid class "staggered"
// (Blender's and Houdini's fluid velocities), keeps its components where they are stored, half a
// voxel below the voxel centre along their own axis; the kernel reads them there. NanoVDB files
// are refused by name (velocity grids come from OpenVDB files only).
#pragma once
#include <array>
#include <cstdint>
#include <string>

#include "volume/volume.h"

namespace spectrack {

struct VelocityGrid {
  GridData grid;                      // a NanoVDB Vec3f grid (values as stored: grid units, outliers zeroed)
  bool staggered = false;             // grid class "staggered" (MAC)
  std::array<double, 3> max_abs{};    // largest |component| over active values and the background
  double max_speed = 0;               // largest |v| over active values and the background
  uint64_t outliers = 0;              // active values zeroed as outliers
};

// Loads vec3s grid `grid_name` of a .vdb file; values longer than `outlier_speed` (grid units),
// active ones and the background, become 0. Throws spectrack::Error (prefixed by `context`, naming the file and grid) for a .nvdb
// file, a missing or non-vec3s grid, a non-affine transform and non-finite values (background
// included).
VelocityGrid load_velocity_grid(const std::string& file, const std::string& grid_name, double outlier_speed,
                                const std::string& context);

// The largest |component| of the stored values over the voxels lo .. hi (inclusive, index
// coordinates), the values of tiles and the background met there included: each component of the
// trilinear (or staggered) velocity at a point whose interpolation reads only voxels of the box
// is a convex combination of them, so it stays within these bounds.
std::array<double, 3> velocity_max_abs(const VelocityGrid& v, const std::array<int, 3>& lo, const std::array<int, 3>& hi);

}  // namespace spectrack
