// volume.h: loading density/emission grids from OpenVDB (.vdb) and NanoVDB (.nvdb) files into
// NanoVDB float grids for the device, and building the sparse majorant/minorant grid.
//
// Conventions (shared with kernels/medium.h): values sit at integer index coordinates; the
// density at a continuous index point p is the trilinear interpolation of the 8 voxels
// floor(p) .. floor(p)+1 (inactive voxels read the background, which must be 0). So the density
// can be non-zero only inside (index_min - 1, index_max + 1). The majorant grid covers the box
// [origin, origin + dims * cell) with origin = index_min - 1; cell (i,j,k) spans
// [origin + (i,j,k)*cell, origin + (i,j,k)*cell + cell) and stores the max and min over its
// trilinear support, voxels origin + c*cell ... origin + (c+1)*cell inclusive on each axis
// (docs/estimators.md, 'The trilinear-support rule'), so dmin <= density(p) <= dmax for every p in the cell.
#pragma once
#include <array>
#include <functional>
#include <list>
#include <string>
#include <vector>

#include <nanovdb/util/GridHandle.h>

#include "kernels/types.h"
#include "util/error.h"

namespace spectrack {

struct GridData {
  std::string file;  // as opened
  std::string name;  // grid name in the file
  nanovdb::GridHandle<nanovdb::HostBuffer> handle;  // one float grid
  std::array<int, 3> index_min{0, 0, 0};  // active-value index bbox, inclusive
  std::array<int, 3> index_max{-1, -1, -1};
  bool empty = true;                      // no active values
  double index_to_world[3][4] = {};       // the file's own affine index->world map
  float value_min = 0, value_max = 0;     // over active values
};

// Loads float grid `grid_name` (index `grid_index` among grids of that name, or the first one
// with a warning on stderr when several share the name and grid_index < 0) from a .vdb or .nvdb
// file. `context` prefixes messages (e.g. "scene.json: /media/0"). Throws spectrack::Error for a
// missing/unreadable/corrupt file, a missing grid (listing the grids present), a non-float grid,
// a level set, a non-affine transform, a non-zero background, and negative or NaN values.
GridData load_float_grid(const std::string& file, const std::string& grid_name, int grid_index,
                         const std::string& context);

// While a KeptGrids lives (one at a time, in any thread), the grids loaded through its load() stay
// in memory, and the next load_float_grid of the same file, grid name and index hands the kept grid
// over (moved out, once) instead of reading the file again: `spectrack info` reports a grid and
// then packs the scene as `render` does with one read of each file.
class KeptGrids {
 public:
  KeptGrids();
  ~KeptGrids();
  KeptGrids(const KeptGrids&) = delete;
  KeptGrids& operator=(const KeptGrids&) = delete;
  // load_float_grid's grid (its checks and messages), kept; a grid kept already is not read again.
  // The reference holds until the grid is handed over or the KeptGrids dies.
  const GridData& load(const std::string& file, const std::string& grid_name, int grid_index,
                       const std::string& context);

  struct Entry {
    std::string file, grid_name;
    int grid_index;
    GridData grid;
  };

 private:
  std::list<Entry> entries_;
  friend bool take_kept_grid(const std::string&, const std::string&, int, GridData*);
};

// Loads the vec3s grid `grid_name` of a .vdb file (a medium's colour, e.g. Houdini's Cd) as three
// float grids, its x, y and z components, each with the vec3 grid's transform and background
// component (inactive voxels read the background). value_min/value_max span the active values and
// the background. Throws spectrack::Error for a .nvdb file, a missing or non-vec3s grid, a
// non-affine transform, and negative or non-finite values (background included).
std::array<GridData, 3> load_color_grid(const std::string& file, const std::string& grid_name,
                                        const std::string& context);

// Names and types of the grids in a file, "name (type, class)" each, for messages and `info`.
std::vector<std::string> list_grids(const std::string& file);
// Whether a list_grids() listing has a grid named `name`.
bool grid_listed(const std::vector<std::string>& listing, const std::string& name);

struct MajorantGrid {
  std::array<int, 3> origin{0, 0, 0};  // index-space origin (= index_min - 1)
  std::array<int, 3> dims{1, 1, 1};    // cells per axis
  int cell = 8;                        // voxels per cell edge
  std::vector<float> dmax, dmin;       // x fastest, then y, then z
};

// Builds the majorant grid of `grid` with `cell` voxels per cell edge. dmax is inflated by a
// relative 1e-5 (float rounding of the interpolation), dmin deflated likewise. An empty grid
// gives a single cell with dmax = dmin = 0. margin: a moving medium's lookups reach up to
// margin[a] voxels away along axis a (motion blur, kernels/medium.h medium_lookup_index): the
// box grows by margin[a] voxels on both faces and each cell's support by margin[a] voxels on both
// sides, so the cell bounds the density at every point its lookups can reach (0: the plain grid).
// cell_reach, when given, narrows that per cell: for a cell whose support spans the voxels
// lo .. hi (inclusive; cell edges on voxel centres) it returns how far (voxels, fractional, clamped
// to 0 .. margin) the lookups of points inside the cell can reach along each axis, and the cell
// bounds the trilinear density over its extent grown by exactly that; the box, and the cells that
// read only the background, stay those of margin. Where those bounds would read more than
// exact_read_limit voxels (a reach of many voxels: about (cell + 2 margin)^3 per cell), each cell
// is bounded instead by the 8^3 leaves and tiles its grown extent meets, a read per leaf: wider by
// at most the 7 voxels that round the extent out to leaves, valid all the same.
using CellReach = std::function<std::array<double, 3>(const std::array<int, 3>& lo, const std::array<int, 3>& hi)>;
constexpr double kExactMotionBoundReads = 1e9;
MajorantGrid build_majorant_grid(const GridData& grid, int cell = 8, const std::array<int, 3>& margin = {0, 0, 0},
                                 const CellReach& cell_reach = {}, double exact_read_limit = kExactMotionBoundReads);
// The largest majorant cell edge (voxels): --majorant-cell and the automatic choice stay within it.
// A grid that needs more than 2^27 cells even at this edge is refused by build_majorant_grid.
constexpr int kMaxMajorantCellEdge = 1024;

// The blocks of a majorant grid walked whole (the coarsest level of the hierarchy below): blocks of `block`^3 cells of `fine` (partial
// blocks at the far faces), each with the max dmax and min dmin of its cells, so a block with
// dmax = 0 has only empty cells and the DDA can cross it in one step.
MajorantGrid coarsen_majorant_grid(const MajorantGrid& fine, int block);

// The adaptive majorant hierarchy the kernels walk (kernels/majorant.h, docs/majorant-hierarchy.md):
// blocks of `block`^3 fine cells, each walked at its own level: in groups of r^3 fine cells (r =
// 1, 2, 4, .. dividing the block edge, or the block edge itself: the block walked whole), each
// group bounded by the max dmax and min dmin of its cells. The level of each block is the
// cheapest under a cost model of DDA steps and density lookups per unit length of ray.
struct MajorantCostModel {
  // density lookups per unit index length per unit density: the largest channel's sigma_t (per
  // unit density, density_scale included) times the voxel's world length
  double lookups_per_density = 1.0;
  bool decompose = false;   // the tracker's residual is dmax - dmin (else dmax)
  double step_cost = 0.6;   // one DDA step into a non-empty group (with its new free flight), in lookups
};
struct MajorantHierarchy {
  int block = 8;                        // fine cells per block edge (>= 2)
  std::array<int, 3> block_dims{1, 1, 1};
  // per block (x fastest): its entry (kernels/types.h st_maj_block): group == block, walked
  // whole; group = r < block, walked in groups of r^3 cells whose (block/r)^3 bounds lie at pair
  // `pool` of the pool, x fastest (groups past the grid's far faces: (0, 0))
  std::vector<st_maj_block> blocks;
  std::vector<float> pool;  // (dmax, dmin) pairs
  std::vector<int> levels;              // the group edges, finest first
  std::vector<size_t> blocks_per_level; // blocks walked at each level
  size_t blocks_empty = 0, blocks_whole = 0, blocks_refined = 0;
};

// Chooses each block's level: the least step_cost * 1.5 / edge * (f + (1 - f) / 4) (1.5: the
// mean DDA crossings per unit length of an isotropic ray through cubes of unit edge; f: the
// fraction of non-empty groups) plus lookups_per_density times the mean residual of its groups;
// ties go to the coarser level. Throws spectrack::Error for block < 2.
MajorantHierarchy build_majorant_hierarchy(const MajorantGrid& fine, int block, const MajorantCostModel& cost);

// The bounds (dmax, dmin) the walk uses at fine cell (i, j, k): its group's (the host mirror of
// kernels/majorant.h majorant_bounds_at). Throws spectrack::Error naming the block when its entry
// is not one the builder makes (a group edge that does not divide the block, groups past the pool).
std::array<float, 2> majorant_hierarchy_bounds(const MajorantHierarchy& h, int i, int j, int k);

// The block entries as the majorant buffer holds them (two float2 records each, the layout of
// st_maj_block), appended to words; and entry b of the entries starting at pair `offset`.
void append_majorant_blocks(std::vector<float>& words, const std::vector<st_maj_block>& blocks);
st_maj_block packed_majorant_block(const std::vector<float>& words, size_t offset, size_t b);

// Host-side trilinear density at a continuous index point (the reference for device lookups).
float sample_index_trilinear(const GridData& grid, double x, double y, double z);

}  // namespace spectrack
