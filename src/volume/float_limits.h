// float_limits.h: what the float kernels can track, checked when a medium is packed for the
// device: coefficients that are not finite as floats, extinctions whose products overflow, and
// optical depths per voxel beyond what float tracking resolves are refused with an Error that
// names the field (and the voxel).
//
// The limits (README, "Scenes"):
//  - sigma_a, sigma_s times density_scale must be finite floats (<= FLT_MAX, about 3.4e38).
//  - the largest extinction mu = max over channels of (sigma_a + sigma_s) * density_scale *
//    (largest density) * max(1, majorant_scale, minorant_scale) must be at most 2^60 (about
//    1.2e18): the event weights multiply two coefficients and a path weight (mu_bar * P in
//    kernels/tracking.h), and 2^60 * 2^60 leaves a factor 2^8 below FLT_MAX = 2^128.
//  - VDB media: the optical depth across one voxel (mu times the longest world edge of a voxel)
//    must be at most 2^24. A float resolves a segment into about 2^24 parameter values, and a
//    segment is at least a voxel long (a majorant cell is one or more voxels), so beyond 2^24 the
//    mean free flight is shorter than the float spacing over a voxel-long segment, even measured
//    from the segment's start; and a walk across such a voxel needs more than 2^24 (1.7e7)
//    tentative collisions, a second or more of one core per ray for every voxel crossed.
//    density_scale 1e6 on smoke1 (9e5 per voxel) is inside the limit.
//  - homogeneous media have a tight majorant (no null collisions to pay for), so their size is
//    no limit (an "infinite" medium is a box of any size); there the mean free path must exceed
//    the float spacing of world coordinates at the box's point nearest the origin, or scattering
//    points could not move.
// Infinite or NaN voxels are refused when the grid is loaded (volume.cpp).
#pragma once
#include <string>

#include "kernels/types.h"
#include "scene/scene.h"
#include "volume/volume.h"

namespace spectrack {

constexpr double kMaxExtinction = 1152921504606846976.0;  // 2^60
constexpr double kMaxOpticalDepthPerVoxel = 16777216.0;    // 2^24

// Checks medium `md` as packed into `packed` (coefficients already times density_scale, world
// to index rows set) with its density grid `grid` (nullptr for a homogeneous medium, whose
// density is 1 and whose "voxel" is its box). `context` names the medium ("scene.json:
// /media/0"). Throws spectrack::Error.
void check_float_limits(const MediumDesc& md, const st_medium& packed, const GridData* grid,
                        const std::string& context);

// The majorant cell edge (voxels) for a VDB medium: `requested`, halved while a cell's optical
// depth at the grid's largest density (extinction times the cell's longest world edge) exceeds
// kMaxOpticalDepthPerCell and the finer grid stays within kMaxMajorantCells. A ray that crosses
// the empty part of a cell holding dense voxels takes about that many tentative collisions, so
// very thick media (density_scale 1e6 on smoke1: 7e6 per 8-voxel cell) get tighter cells;
// ordinary media (below 8192 per voxel at the default 8) keep the requested edge.
constexpr double kMaxOpticalDepthPerCell = 65536.0;  // 2^16
constexpr double kMaxMajorantCells = 33554432.0;     // 2^25 cells (256 MiB of (dmax, dmin))
int majorant_cell_for(const st_medium& packed, const GridData& grid, double majorant_scale, int requested);

// The automatic fine-cell edge of the majorant hierarchy (--majorant-cell 0, the default): 2
// voxels, doubled while the fine grid over the grid's active box would exceed kAutoMajorantCells
// (its build reads about (1 + 1/cell)^3 voxels per voxel of the box; the stored hierarchy keeps
// only the refined blocks, docs/majorant-hierarchy.md).
constexpr double kAutoMajorantCells = 4194304.0;  // 2^22
int auto_majorant_cell(const GridData& grid);

// Longest world-space edge of one index-space unit: the column norms of index -> world, the
// inverse of the packed world -> index rows.
double longest_voxel_edge(const st_medium& m);

}  // namespace spectrack
