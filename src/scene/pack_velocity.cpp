// pack_velocity.cpp: a moving medium's velocity grid in the packed scene (motion blur,
// kernels/medium.h medium_lookup_index; docs/scene-format.md, "Motion blur").
//
// Design: the kernels displace a lookup at index point x by velocity_to_index v(x) t, so the host
// folds everything constant into that matrix: the inverse of the file's index-to-world linear
// part (the velocity is in the file's world units; a medium's "transform" moves and scales the
// medium with its flow, so it cancels), the velocity scale and the frame rate. The majorants need
// how far a lookup can be displaced: reach_a = max |t| * sum_b |velocity_to_index_ab| * max |v_b|,
// per majorant cell (max |v_b| over the velocity voxels the cell's points interpolate: the trilinear
// or staggered velocity is a convex combination of them) and over the whole grid (which grows the
// grid's box); build_majorant_grid bounds each cell's density over its extent grown by its own
// reach. A medium that cannot move (no shutter, a shutter at time 0, scale 0 or a grid of zeros)
// gets no velocity grid: its kernels and image are those of a still medium.
#include "scene/packer.h"

#include <fmt/format.h>

#include <cmath>
#include <limits>
#include <memory>

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

MotionReach Packer::add_velocity_grid(st_medium& m, const MediumDesc& md, const GridData& density,
                                      const std::string& ctx_name) {
  const VelocityDesc& vd = md.velocity;
  const std::string ctx = ctx_name + "/velocity";
  const double per_second = vd.scale * (vd.fps > 0 ? vd.fps : 1.0);
  const double outlier_speed = per_second != 0 ? vd.outlier_threshold / std::abs(per_second)
                                               : std::numeric_limits<double>::infinity();
  auto v = std::make_shared<VelocityGrid>(load_velocity_grid(md.file, vd.grid, outlier_speed, ctx));
  if (!same_index_to_world(v->grid, density))
    throw Error(fmt::format("{}/grid: grid '{}' has a different index-to-world transform than density grid '{}'; "
                            "both grids must share one transform (resample one onto the other)",
                            ctx, vd.grid, md.grid));
  MotionReach out;
  if (!(shutter_reach > 0) || per_second == 0 || !(v->max_speed > 0)) return out;
  Mat4 linear;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) linear.m[r][c] = density.index_to_world[r][c];
  const Mat4 inv = inverse_affine(linear, ctx + "/grid");
  std::array<std::array<double, 3>, 3> k{};  // max |t| |velocity_to_index_ab|
  for (int r = 0; r < 3; ++r) {
    double row[3];
    for (int c = 0; c < 3; ++c) {
      row[c] = inv.m[r][c] * per_second;
      k[size_t(r)][size_t(c)] = std::abs(row[c]) * shutter_reach;
    }
    m.velocity_to_index[r] = f4(row[0], row[1], row[2]);
  }
  // reach_a = max |t| sum_b |velocity_to_index_ab| max |v_b|, with a margin for the float rounding
  // of the kernel's displacement; 0 where no velocity component that moves along a is nonzero
  // (the kernel's displacement along a is then exactly 0)
  auto reach_of = [k](const std::array<double, 3>& v_max) {
    std::array<double, 3> reach{0, 0, 0};
    for (size_t a = 0; a < 3; ++a) {
      for (size_t b = 0; b < 3; ++b) reach[a] += k[a][b] * v_max[b];
      if (reach[a] > 0) reach[a] = reach[a] * (1 + 1e-4) + 1e-3;
    }
    return reach;
  };
  out.reach = reach_of(v->max_abs);
  for (int a = 0; a < 3; ++a)
    if (!std::isfinite(out.reach[size_t(a)]) || out.reach[size_t(a)] > 1e7)
      throw Error(fmt::format("{}/scale: the largest displacement over the shutter, {:.6g} voxels, is out of range", ctx,
                              out.reach[size_t(a)]));
  // A lookup at x in a cell (voxels lo .. hi along each axis) reads v at x, which interpolates
  // voxels lo .. hi (a staggered component a at x + 1/2 along a: up to hi + 1), so the largest
  // |v_b| there bounds its displacement (docs/scene-format.md, "Motion blur"). A point that float
  // rounding puts up to 1e-3 voxels outside its cell mixes in a neighbour's velocity with that
  // weight, which moves it by at most 2e-3 of the global reach: added to every cell's reach.
  // A one-voxel (stochastic) lookup reads a voxel of the displaced point's trilinear support, not
  // the blend of its corners, so its cells bound the voxels within the reach rounded up.
  const int up = v->staggered ? 1 : 0;
  out.cell_reach = [v, reach_of, up, global = out.reach, whole = stochastic_lookup](const std::array<int, 3>& lo,
                                                                                   const std::array<int, 3>& hi) {
    std::array<double, 3> r = reach_of(velocity_max_abs(*v, lo, {hi[0] + up, hi[1] + up, hi[2] + up}));
    for (size_t a = 0; a < 3; ++a) {
      r[a] += 2e-3 * global[a];
      if (whole) r[a] = std::ceil(r[a]);
    }
    return r;
  };
  m.velocity_grid[0] = upload_grid(ctx, v->grid);
  m.velocity_grid[1] = m.velocity_grid[2] = ST_NO_GRID;
  m.velocity_grid[3] = v->staggered ? 1u : 0u;
  return out;
}

}  // namespace packing
}  // namespace spectrack
