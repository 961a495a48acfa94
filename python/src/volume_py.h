// volume_py.h: the Python module's Volume: a float grid usable as a medium's density.
//
// Design: Volume.from_numpy builds an OpenVDB FloatGrid in memory, activating only the non-zero
// voxels (the background is 0, so the grid is sparse where the array is zero), with the linear
// transform of voxel_size and origin. The renderer reads media from files (their contents enter
// the scene hash that identifies a render's pieces), so the grid is written once, with its
// checks, to a .vdb in a private temporary folder that the Volume owns and removes; a scene
// built by load_dict refers to that file, and renders exactly as the same grid saved by the user.
// Volume.from_file refers to a file the user has.
#pragma once
#include <pybind11/pybind11.h>

#include <array>
#include <string>

namespace spectrack {
namespace python {

struct Volume {
  std::string file;          // the .vdb the scene refers to
  std::string grid = "density";
  std::string temp_dir;      // from_numpy: the private folder holding `file` (removed with the Volume)
  std::array<int, 3> shape{0, 0, 0};
  uint64_t active_voxels = 0;
  Volume() = default;
  Volume(const Volume&) = delete;
  Volume& operator=(const Volume&) = delete;
  ~Volume();
};

void bind_volume(pybind11::module_& m);

}  // namespace python
}  // namespace spectrack
