// presets.h: medium presets for simulation caches ("preset" of a vdb medium, docs/scene-format.md
// "Presets"): the density grid, its coefficients and phase, and a blackbody emission from the
// cache's fire grids, chosen so that a Houdini pyro or Blender fire cache renders as a fire with
// no tuning. A preset only sets defaults: every field the scene gives overrides it (an "emission"
// replaces the preset's whole emission).
//
// The emission is blackbody (normalization "none": physical radiance, growing as T^4) under the
// "density" model (its brightness independent of the smoke's sigma_a), with the
// temperature T = value x temperature_scale of the first of the preset's fire grids the file has,
// each with its own scale (EmissionDesc::temperature_grid_choices); a file with none of them
// renders as smoke, with a warning.
#pragma once
#include <string>

namespace spectrack {

struct MediumDesc;

// Sets m's defaults to preset `name`; false when there is no such preset.
bool apply_medium_preset(const std::string& name, MediumDesc* m);
std::string medium_preset_names();  // "houdini-pyro, blender"

}  // namespace spectrack
