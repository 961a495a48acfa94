// kept_grids.cpp: KeptGrids (volume.h): grids kept loaded while one lives, handed over once to the
// load_float_grid that asks for the same file, grid name and index (take_kept_grid).
#include <list>
#include <mutex>
#include <stdexcept>
#include <string>
#include <utility>

#include "volume/volume.h"
#include "volume/volume_detail.h"

namespace spectrack {

namespace {
std::mutex kept_mutex;
KeptGrids* kept_grids = nullptr;  // the living KeptGrids, if any
}  // namespace

KeptGrids::KeptGrids() {
  std::lock_guard<std::mutex> lock(kept_mutex);
  if (kept_grids) throw std::logic_error("KeptGrids: one lives already");
  kept_grids = this;
}

KeptGrids::~KeptGrids() {
  std::lock_guard<std::mutex> lock(kept_mutex);
  kept_grids = nullptr;
}

const GridData& KeptGrids::load(const std::string& file, const std::string& grid_name, int grid_index,
                                const std::string& context) {
  {
    std::lock_guard<std::mutex> lock(kept_mutex);
    for (const Entry& e : entries_)
      if (e.file == file && e.grid_name == grid_name && e.grid_index == grid_index) return e.grid;
  }
  GridData g = load_float_grid(file, grid_name, grid_index, context);
  std::lock_guard<std::mutex> lock(kept_mutex);
  entries_.push_back({file, grid_name, grid_index, std::move(g)});
  return entries_.back().grid;
}

// Moves the kept grid of (file, grid_name, grid_index) into *out and forgets it; false if none.
bool take_kept_grid(const std::string& file, const std::string& grid_name, int grid_index, GridData* out) {
  std::lock_guard<std::mutex> lock(kept_mutex);
  if (!kept_grids) return false;
  std::list<KeptGrids::Entry>& entries = kept_grids->entries_;
  for (auto it = entries.begin(); it != entries.end(); ++it)
    if (it->file == file && it->grid_name == grid_name && it->grid_index == grid_index) {
      *out = std::move(it->grid);
      entries.erase(it);
      return true;
    }
  return false;
}

}  // namespace spectrack
