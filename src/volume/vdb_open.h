// vdb_open.h: internal to src/volume: opening a .vdb with the loaders' structural checks
// (volume.cpp), for the grid inspection of inspect.cpp.
#pragma once
#include <memory>
#include <string>

#include <openvdb/openvdb.h>

#include "volume/vdb_prescan.h"
#include "volume/volume_detail.h"

namespace spectrack {
namespace volume_detail {
// Checks the file is readable, pre-scans its structure and opens it (throws spectrack::Error);
// the pre-scan's layout goes to `layout` for check_vdb_tree before each grid is read.
std::unique_ptr<openvdb::io::File> open_vdb_checked(const std::string& file, const Fail& fail, VdbLayout* layout = nullptr);
// Fails when a grid's tree disagrees with its file_bbox metadata (damaged files).
void check_vdb_file_bbox(const openvdb::GridBase& g, const Fail& fail);
}  // namespace volume_detail
}  // namespace spectrack
