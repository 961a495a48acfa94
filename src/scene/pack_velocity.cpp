// pack_velocity.cpp: a moving medium's velocity grid in the packed scene (motion blur,
// kernels/medium.h medium_lookup_index; docs/scene-format.md, "Motion blur").
//
// Design: the kernels displace a lookup at index point x by velocity_to_index v(x) t, so the host
// folds everything constant into that matrix: the inverse of the file's index-to-world linear
// part (the velocity is in the file's world units; a medium's "transform" moves and scales the
// medium with its flow, so it cancels), the velocity scale and the frame rate. The bound the
// majorants need is the largest index displacement along each axis over the shutter:
// reach_a = max |t| * sum_b |velocity_to_index_ab| * max |v_b| over the grid (a global bound, not
// per cell: the trilinear or staggered velocity is a convex combination of voxel values, so each
// component stays within the grid's largest |component|). A medium that cannot move (no shutter,
// a shutter at time 0, scale 0 or a grid of zeros) gets no velocity grid: its kernels and image
// are those of a still medium.
#include "scene/packer.h"

#include <fmt/format.h>

#include <cmath>
#include <limits>

#include "volume/velocity_grid.h"

namespace spectrack {
namespace packing {

bool same_index_to_world(const GridData& a, const GridData& b) {
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 4; ++k)
      if (std::abs(a.index_to_world[r][k] - b.index_to_world[r][k]) > 1e-6 * (1 + std::abs(b.index_to_world[r][k])))
        return false;
  return true;
}

std::array<double, 3> Packer::add_velocity_grid(st_medium& m, const MediumDesc& md, const GridData& density,
                                                const std::string& ctx_name) {
  const VelocityDesc& vd = md.velocity;
  const std::string ctx = ctx_name + "/velocity";
  const double per_second = vd.scale * (vd.fps > 0 ? vd.fps : 1.0);
  const double outlier_speed = per_second != 0 ? vd.outlier_threshold / std::abs(per_second)
                                               : std::numeric_limits<double>::infinity();
  VelocityGrid v = load_velocity_grid(md.file, vd.grid, outlier_speed, ctx);
  if (!same_index_to_world(v.grid, density))
    throw Error(fmt::format("{}/grid: grid '{}' has a different index-to-world transform than density grid '{}'; "
                            "both grids must share one transform (resample one onto the other)",
                            ctx, vd.grid, md.grid));
  std::array<double, 3> reach{0, 0, 0};
  if (!(shutter_reach > 0) || per_second == 0 || !(v.max_speed > 0)) return reach;
  Mat4 linear;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) linear.m[r][c] = density.index_to_world[r][c];
  const Mat4 inv = inverse_affine(linear, ctx + "/grid");
  for (int r = 0; r < 3; ++r) {
    double row[3];
    for (int c = 0; c < 3; ++c) {
      row[c] = inv.m[r][c] * per_second;
      reach[size_t(r)] += std::abs(row[c]) * v.max_abs[size_t(c)];
    }
    m.velocity_to_index[r] = f4(row[0], row[1], row[2]);
    // float rounding of the kernel's displacement, and a margin
    reach[size_t(r)] = reach[size_t(r)] * shutter_reach * (1 + 1e-4) + 1e-3;
    if (!std::isfinite(reach[size_t(r)]) || reach[size_t(r)] > 1e7)
      throw Error(fmt::format("{}/scale: the largest displacement over the shutter, {:.6g} voxels, is out of range", ctx,
                              reach[size_t(r)]));
  }
  m.velocity_grid[0] = upload_grid(ctx, v.grid);
  m.velocity_grid[1] = m.velocity_grid[2] = ST_NO_GRID;
  m.velocity_grid[3] = v.staggered ? 1u : 0u;
  return reach;
}

}  // namespace packing
}  // namespace spectrack
