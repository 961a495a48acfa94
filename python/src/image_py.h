// image_py.h: the Python module's Image: a film piece (film/film.h) with its statistics, shown
// to Python as numpy arrays. The arrays are made by the functions the EXR writer uses
// (piece_beauty, piece_exr_channels), so an array holds exactly the floats a file would.
#pragma once
#include <pybind11/pybind11.h>

#include <nlohmann/json.hpp>

#include "image/image.h"
#include "film/film.h"
#include "integrator/renderer.h"

namespace spectrack {
namespace python {

struct Image {
  FilmPiece piece;
  RenderStats counters;     // summed over the pieces merged into this one
  nlohmann::json stats;     // render_stats_json of a render; the merge's summary for a merge
  Metadata meta;            // written beside the piece's own metadata
  bool spp_or_pixel_range = false;  // rendered with spp_range or pixel_bounds: a piece to merge
};

// Binds Image, merge, read and read_exr to module `m`.
void bind_image(pybind11::module_& m);

}  // namespace python
}  // namespace spectrack
