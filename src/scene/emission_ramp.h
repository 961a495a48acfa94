// emission_ramp.h: emission "type": "ramp" (docs/scene-format.md): Le = scale * colour(v), v the
// value of the medium's emission grid, colour linear between the stops (value, [r, g, b]) and the
// end stops' colours beyond them.
//
// Design: no kernel code of its own. The ramp becomes the colour table that blackbody emission
// reads (kernels/medium.h blackbody_rgb): the kernels map the grid's value v to T = v - v_lo + 1
// (v_lo = min(0, the grid's smallest value), so T >= 1) and look T up at the warped position
// A / T - B ln T with A = 0, B = -1, i.e. ln T; the table holds the ramp's colours at 4096
// entries evenly spaced in ln T over the grid's values, interpolated linearly. A one-stop ramp is
// one colour everywhere, exactly (constant emission); elsewhere the table is within 1e-4 of the
// ramp's colours (a stop's kink spans at most one entry). RGB mode only: spectral mode refuses it.
#pragma once
#include <array>
#include <cstdint>
#include <utility>
#include <vector>

#include "kernels/types.h"

namespace spectrack {

using RampStops = std::vector<std::pair<double, std::array<double, 3>>>;

// The ramp's colour at value v (stops of increasing value, at least one).
std::array<double, 3> ramp_colour(const RampStops& stops, double v);

// Writes the table for grid values in [value_min, value_max] to grid_words (float4 entries, at
// m.blackbody_offset) and sets m.temperature and m.blackbody_table to read it; returns the
// table's largest colour component.
double pack_emission_ramp(st_medium& m, const RampStops& stops, double value_min, double value_max,
                          std::vector<uint32_t>& grid_words);

}  // namespace spectrack
