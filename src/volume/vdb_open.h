// vdb_open.h: internal to src/volume: opening a .vdb with the loaders' structural checks
// (volume.cpp), for the grid inspection of inspect.cpp.
#pragma once
#include <memory>
#include <string>

#include <openvdb/openvdb.h>

#include "volume/vdb_prescan.h"
#include "volume/volume.h"
#include "volume/volume_detail.h"

namespace spectrack {
namespace volume_detail {
// Checks the file is readable, pre-scans its structure and opens it (throws spectrack::Error);
// the pre-scan's layout goes to `layout` for check_vdb_tree before each grid is read.
std::unique_ptr<openvdb::io::File> open_vdb_checked(const std::string& file, const Fail& fail, VdbLayout* layout = nullptr);
// A grid read from a .vdb file as a vec3s grid: itself, or a vec3d grid (Houdini's 64-bit vectors)
// with its values rounded to float and its metadata and transform kept; null for other types. A
// component beyond a float's range becomes infinite, which the colour and velocity checks refuse.
openvdb::Vec3SGrid::Ptr as_vec3s_grid(const openvdb::GridBase::Ptr& g);
// Whether a value type (GridBase::valueType) reads as a vec3s grid through as_vec3s_grid.
inline bool vec3_value_type(const std::string& type) { return type == "vec3s" || type == "vec3d"; }
// Fails when a grid's tree disagrees with its file_bbox metadata (damaged files).
void check_vdb_file_bbox(const openvdb::GridBase& g, const Fail& fail);
// The active index box and the affine index-to-world map of an OpenVDB grid, into g.
void set_box_and_map(GridData& g, const openvdb::GridBase& grid);
// The component float grids `comp` of a vec3 grid (a colour) as GridData: NanoVDB handles
// named grid_name.x, .y, .z, the vec3 grid's active box and index-to-world map (value ranges are
// the caller's); `what` names the grid in the conversion's error.
std::array<GridData, 3> vec3_components(const openvdb::Vec3SGrid& grid, const std::array<openvdb::FloatGrid::Ptr, 3>& comp,
                                        const std::string& grid_name, const std::string& what, const Fail& fail);
}  // namespace volume_detail
}  // namespace spectrack
