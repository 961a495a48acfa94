// float_limits.h: what the float kernels can track, checked when a medium is packed for the
// device: coefficients that are not finite as floats, extinctions whose products overflow, and
// optical depths per voxel beyond what float tracking resolves are refused with an Error that
// names the field (and the voxel).
//
// The limits (docs/limits.md, "Coordinates and the float range of the kernels"):
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
//  - majorant_scale must be at least 2^-24: below it the majorant s x mu is less than half the float
//    spacing of mu, so mu - s x mu rounds to mu and the majorant drops out of the null-collision
//    weights (tentative collisions 2^24 times rarer than real ones: the medium all but vanishes).
// Coordinates (check_coordinates, once the camera is placed):
//  - every world coordinate (the camera position, a homogeneous box's bounds, the corners of a
//    VDB medium's world box, a transform's translate) must be at most 2^60 (about 1.2e18) in
//    magnitude: the kernels square differences of coordinates (distances, ray-box tests), and
//    3 x (2 x 2^60)^2 stays a factor 2^4 below FLT_MAX.
//  - the float spacing of world coordinates at the farthest of the camera and the medium's box
//    (2^-23 of that distance, rounded down to a power of two) must be at most 1/16 of the
//    medium's shortest voxel edge (a homogeneous box: its shortest side): rays from the camera
//    reach the medium at positions rounded to that spacing, and a coarser spacing moves lookups
//    across voxels (a translate of 1e30 on a unit-voxel grid rounds positions to 7e22).
//    A homogeneous box of half-width 1e6 around the origin (an "infinite" medium) has spacing
//    0.06 against sides of 2e6.
// Infinite or NaN voxels are refused when the grid is loaded (volume.cpp).
#pragma once
#include <string>

#include <vector>

#include "kernels/types.h"
#include "scene/framing.h"
#include "scene/scene.h"
#include "volume/volume.h"

namespace spectrack {

constexpr double kMaxExtinction = 1152921504606846976.0;  // 2^60
constexpr double kMaxOpticalDepthPerVoxel = 16777216.0;    // 2^24
constexpr double kMinMajorantScale = 1.0 / 16777216.0;     // 2^-24
constexpr double kMaxCoordinate = 1152921504606846976.0;   // 2^60
constexpr double kMinVoxelsPerSpacing = 16.0;               // spacing at most 1/16 of a voxel edge

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

// Checks the world coordinates of a packed scene against the rules above: the camera's position
// as placed (framing included), each medium's world box (`boxes`, in the order of scene.media)
// and its shortest voxel edge (from st.media's world -> index rows). Throws Error naming the
// field: /camera/position, /media/<i>/bounds, /media/<i>/transform/translate, /media/<i>/transform
// or, for a grid's own transform, /media/<i>/file.
void check_coordinates(const SceneDesc& scene, const st_scene& st, const std::vector<Box3>& boxes,
                       const Vec3& camera_position);

// Longest world-space edge of one index-space unit: the column norms of index -> world, the
// inverse of the packed world -> index rows.
double longest_voxel_edge(const st_medium& m);
// Shortest, likewise.
double shortest_voxel_edge(const st_medium& m);

}  // namespace spectrack
