// presets.cpp: the medium presets' numbers (presets.h has the design; docs/scene-format.md
// "Presets" lists them).
#include "scene/presets.h"

#include "scene/scene.h"

namespace spectrack {
namespace {

struct MediumPreset {
  const char* name;
  double sigma_s, sigma_a, g;  // per unit density, grey
  std::vector<std::pair<std::string, double>> fire_grids;  // (grid, temperature_scale in K per unit value)
  double emission_scale;  // of the "density" emission model: the source is density x scale x B(T)
};

// Houdini pyro: smoke of low albedo with a mild forward lobe; temperature (ambient 0, about 1 to 2
// in flames) at 1500 K per unit, heat and flame (0 .. 1) at 2600 K per unit: a flame core near
// 2600 K, orange to yellow. Blender (Mantaflow): its Principled Volume's defaults (density 1, colour
// 0.5: sigma_s = sigma_a = 0.5, anisotropy 0) and its Temperature of 1000 K times the temperature
// attribute; flame (0 .. 1) at 2000 K per unit.
const MediumPreset kPresets[] = {
    {"houdini-pyro", 0.1, 0.3, 0.3, {{"temperature", 1500.0}, {"heat", 2600.0}, {"flame", 2600.0}}, 0.6},
    {"blender", 0.5, 0.5, 0.0, {{"flame", 2000.0}, {"temperature", 1000.0}}, 1.0},
};

}  // namespace

bool apply_medium_preset(const std::string& name, MediumDesc* m) {
  for (const MediumPreset& p : kPresets) {
    if (name != p.name) continue;
    m->grid = "density";
    m->density_scale = 1.0;
    m->sigma_s = {p.sigma_s, p.sigma_s, p.sigma_s};
    m->sigma_a = {p.sigma_a, p.sigma_a, p.sigma_a};
    m->phase = PhaseDesc{};
    if (p.g != 0) {
      m->phase.type = ST_PHASE_HG;
      m->phase.g = p.g;
      m->phase.name = "hg";
    }
    m->emission = EmissionDesc{};
    m->emission.present = true;
    m->emission.blackbody = true;
    m->emission.normalization = BlackbodyNorm::None;
    m->emission.scale = p.emission_scale;
    m->emission.per_density = true;
    m->emission.temperature_grid_choices = p.fire_grids;
    return true;
  }
  return false;
}

std::string medium_preset_names() {
  std::string s;
  for (const MediumPreset& p : kPresets) s += (s.empty() ? "" : ", ") + std::string(p.name);
  return s;
}

}  // namespace spectrack
