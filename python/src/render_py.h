// render_py.h: Scene.render of the Python module (render_py.cpp).
#pragma once
#include <pybind11/pybind11.h>

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "image_py.h"
#include "scene/scene.h"

namespace spectrack {
namespace python {

// The keyword arguments of Scene.render (docs/python.md); unset ones leave the scene's value.
struct RenderArgs {
  std::optional<int> spp;
  std::optional<int64_t> seed;
  std::string device;
  std::optional<std::pair<int64_t, int64_t>> spp_range;
  std::optional<std::array<int, 4>> pixel_bounds;
  std::optional<std::string> tracker, scheme;
  std::optional<std::string> guiding;  // "off", "on", "auto" (render.guiding)
  std::string guide_cache;             // a trained guide cache's file (--guide-cache), else ""
  std::optional<bool> alpha;
  std::vector<std::string> aovs;
  std::optional<double> time_limit;
  int chunk_spp = 0;
  bool verbose = false;
  pybind11::object progress = pybind11::none();
  std::string json_text;  // the JSON a scene made in memory was parsed from (its hash), else ""
  std::optional<bool> guide_splitting;  // --guide-splitting: guided roulette and splitting
};

Image render(const SceneDesc& scene, const RenderArgs& args);

}  // namespace python
}  // namespace spectrack
