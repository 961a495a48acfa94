// pack_warnings.cpp: the packer's warnings of scenes that render, but slowly: paths that never end
// (Packer::warn_long_paths) and a motion blur whose majorant bounds read too many voxels
// (warn_slow_motion_bounds). Each text names the scene's field and the ways out.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "scene/packer.h"
#include "util/warning.h"
#include "volume/volume.h"

namespace spectrack {
namespace packing {

// A moving medium's majorant bounds read each cell's voxels widened by the reach on each side, or
// past volume.h's kExactMotionBoundReads the 8^3 leaves that extent meets (build_majorant_grid):
// warned of where that is still minutes of reads.
void warn_slow_motion_bounds(const GridData& g, int cell, const std::array<int, 3>& margin,
                             const std::array<double, 3>& reach, const std::string& ctx_name) {
  if (margin[0] <= 0 && margin[1] <= 0 && margin[2] <= 0) return;
  double voxels = 1, leaves = 1;
  for (size_t a = 0; a < 3; ++a) {
    const double cells = std::ceil((double(g.index_max[a]) - g.index_min[a] + 2 + 2.0 * margin[a]) / cell);
    voxels *= cells * (cell + 2.0 * reach[a] + 1);
    leaves *= cells * (std::ceil((cell + 2.0 * reach[a]) / 8) + 1);
  }
  const bool by_leaf = voxels > kExactMotionBoundReads;
  const double reads = by_leaf ? leaves : voxels;
  if (reads > (by_leaf ? kSlowMotionLeafReads : kSlowMotionBoundVisits))
    warn(fmt::format("{}/velocity: the medium moves up to ({:.3g}, {:.3g}, {:.3g}) voxels over the shutter, and the "
                     "majorant's bounds read every {} within that reach of each cell: about {:.2g} reads, which may "
                     "take minutes (lower the velocity's scale or shorten the shutter for a faster load)",
                     ctx_name, reach[0], reach[1], reach[2], by_leaf ? "8^3 leaf" : "voxel",
                     reads));
}

// A random walk at albedo a in a medium tau mean free paths across scatters about
// min(tau^2, 1 / (1 - a)) times before it leaves or its weight fades (diffusion; absorption), and the
// roulette ends a path only once its weight has fallen: an albedo of 1 leaves its length to tau^2.
void Packer::warn_long_paths(const MediumDesc& md, double tau, const std::string& ctx_name) const {
  if (scene.render.max_depth || !(tau > 1)) return;
  double albedo = 0;
  for (int c = 0; c < 3; ++c) {
    const double t = md.sigma_s[c] + md.sigma_a[c];
    if (t > 0) albedo = std::max(albedo, md.sigma_s[c] / t);
  }
  const double events = std::min(tau * tau, albedo < 1 ? 1.0 / (1.0 - albedo) : tau * tau);
  if (events < kLongPathEvents) return;
  warn(fmt::format("{}: a path takes about {:.2g} scattering events here (about {:.3g} mean free paths across, albedo "
                   "{:.6g}: absorption hardly ends a path) and render.max_depth is unlimited: the render may take very "
                   "long; set render.max_depth (e.g. 1000), give the medium some absorption (sigma_a) or set a time "
                   "limit",
                   ctx_name, events, tau, albedo));
}

}  // namespace packing
}  // namespace spectrack
