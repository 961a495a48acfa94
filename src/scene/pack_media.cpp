// pack_media.cpp: the media of a packed scene: transforms composed in double precision (scale,
// then rotations about x, y, z, then translation: docs/scene-format.md, `transform`; only the
// final world-to-index rows are rounded to float), NanoVDB grids, majorant grids and their
// adaptive hierarchy, colour and temperature grids, and the emission bounds.
#include "scene/packer.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>

#include "color/spectrum.h"
#include "image/image.h"
#include "scene/radiance.h"
#include "scene/emission_ramp.h"
#include "volume/float_limits.h"
#include "scene/media_bounds.h"
#include "integrator/memory_budget.h"
#include "scene/framing.h"
#include "volume/volume.h"
#include "util/warning.h"

namespace spectrack {
namespace packing {

// The emission bounds (scene/radiance.h) of a blackbody medium whose brightest colour component
// up to T_hi kelvin, before `scale`, is `peak` (`what`: "colour"; spectral mode checks its
// brightest spectral radiance as the film reads it as well).
void check_blackbody_bounds(const std::string& ctx, const MediumDesc& md, double peak, double T_hi, double density_max,
                            const char* what) {
  const EmissionDesc& e = md.emission;
  const double le = peak * e.scale;
  const char* why = " (the kernels carry light in single-precision float: see docs/limits.md)";
  if (le > kMaxRadiance)
    throw Error(fmt::format("{}/emission/scale: scale ({}) x the brightest blackbody {} up to {} K ({}, "
                            "normalization {}) = {} is more than {:g}{}, in medium \"{}\"",
                            ctx, e.scale, what, T_hi, peak, blackbody_norm_name(e.normalization), le, kMaxRadiance, why,
                            md.name));
  const double mua = std::max({md.sigma_a[0], md.sigma_a[1], md.sigma_a[2]}) * md.density_scale * density_max;
  if (mua * le > kMaxEmissionProduct)
    throw Error(fmt::format("{}/emission/scale: sigma_a x density_scale x the density's largest value ({}) x the "
                            "brightest blackbody radiance ({}) = {} is more than {:g}{}, in medium \"{}\"",
                            ctx, density_max, le, mua * le, kMaxEmissionProduct, why, md.name));
}

// The brightest spectral radiance of a blackbody at T as the film reads it, before `scale`
// (kernels/medium.h blackbody_spectral_Le; temperatures below the table's floor emit as the floor).
double spectral_blackbody_peak(double T, BlackbodyNorm norm) {
  return film_emission_scale() * blackbody_spectrum_max(std::max(T, kBlackbodyTableFloor), norm);
}

Mat4 inverse_affine(const Mat4& a, const std::string& what) {
  // inverse of [A t; 0 1] = [A^-1, -A^-1 t; 0 1]
  const double(*m)[4] = a.m;
  double det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
               m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
  if (!(std::abs(det) > 1e-300) || !std::isfinite(det)) throw Error(what + ": transform is singular (zero scale?)");
  Mat4 r;
  double inv[3][3];
  inv[0][0] = (m[1][1] * m[2][2] - m[1][2] * m[2][1]) / det;
  inv[0][1] = (m[0][2] * m[2][1] - m[0][1] * m[2][2]) / det;
  inv[0][2] = (m[0][1] * m[1][2] - m[0][2] * m[1][1]) / det;
  inv[1][0] = (m[1][2] * m[2][0] - m[1][0] * m[2][2]) / det;
  inv[1][1] = (m[0][0] * m[2][2] - m[0][2] * m[2][0]) / det;
  inv[1][2] = (m[0][2] * m[1][0] - m[0][0] * m[1][2]) / det;
  inv[2][0] = (m[1][0] * m[2][1] - m[1][1] * m[2][0]) / det;
  inv[2][1] = (m[0][1] * m[2][0] - m[0][0] * m[2][1]) / det;
  inv[2][2] = (m[0][0] * m[1][1] - m[0][1] * m[1][0]) / det;
  for (int i = 0; i < 3; ++i) {
    double t = 0;
    for (int j = 0; j < 3; ++j) {
      r.m[i][j] = inv[i][j];
      t -= inv[i][j] * m[j][3];
    }
    r.m[i][3] = t;
  }
  return r;
}

// The mean length of the chords of a box with sides a over uniformly random lines crossing it
// (Cauchy: 4 V / S).
double mean_chord(const std::array<double, 3>& a) {
  const double S = 2.0 * (a[0] * a[1] + a[1] * a[2] + a[0] * a[2]);
  return S > 0 ? 4.0 * a[0] * a[1] * a[2] / S : 0.0;
}

// The residual majorant of a majorant cell with bounds (dmax, dmin), per unit of sigma_t, as the
// walk's segments take it (kernels/walker.h tracker_segment); without decomposition the majorant.
double residual_majorant(double dmax, double dmin, double majorant_scale, double minorant_scale, bool decompose) {
  if (!decompose) return dmax * majorant_scale;
  const double dc = dmin * minorant_scale;
  return std::max({dmax * majorant_scale - dc, majorant_scale * (dmax - dmin), dc - dmin, 0.0});
}

// The largest channel's extinction per unit density (a colour medium's: its bound sigma_t_maj, at
// which its flights run): the gray rate a shadow ray's lookups scale with.
double max_sigma_t(const st_medium& m) {
  const st_float4 s = m.color_mode != ST_COLOR_NONE
                          ? m.sigma_t_maj
                          : f4(m.sigma_a.x + m.sigma_s.x, m.sigma_a.y + m.sigma_s.y, m.sigma_a.z + m.sigma_s.z);
  return std::max({double(s.x), double(s.y), double(s.z)});
}

// scale, then rotations about x, y, z, then translate (docs/scene-format.md, `transform`)
Mat4 user_transform(const TransformDesc& t) {
  Mat4 S, Rx, Ry, Rz, T;
  for (int i = 0; i < 3; ++i) S.m[i][i] = t.scale[i];
  const double k = M_PI / 180.0;
  double cx = std::cos(t.rotate_deg[0] * k), sx = std::sin(t.rotate_deg[0] * k);
  double cy = std::cos(t.rotate_deg[1] * k), sy = std::sin(t.rotate_deg[1] * k);
  double cz = std::cos(t.rotate_deg[2] * k), sz = std::sin(t.rotate_deg[2] * k);
  Rx.m[1][1] = cx; Rx.m[1][2] = -sx; Rx.m[2][1] = sx; Rx.m[2][2] = cx;
  Ry.m[0][0] = cy; Ry.m[0][2] = sy; Ry.m[2][0] = -sy; Ry.m[2][2] = cy;
  Rz.m[0][0] = cz; Rz.m[0][1] = -sz; Rz.m[1][0] = sz; Rz.m[1][1] = cz;
  for (int i = 0; i < 3; ++i) T.m[i][3] = t.translate[i];
  return T * Rz * Ry * Rx * S;
}

// The hierarchy's automatic step cost (docs/majorant-hierarchy.md, bench/RESULTS.md "Adaptive
// majorant hierarchy"): 0.6 density lookups per DDA step, measured on PoCL, where the render time
// stays level while lookups fall; 2 for spectral trackers that decompose, whose variance grows by
// about 10% with the tighter control of finer levels (media with a control: not colour media) (the control's per-channel collision weights
// replace the residual's history-aware probabilities), which the lookup-only model does not see.
double auto_majorant_step_cost(int tracker, bool has_control) {
  return (has_control && st_tracker_decomposes(tracker) && st_tracker_channels(tracker) == 1) ? kMajorantStepCostControl
                                                                                             : kMajorantStepCost;
}

void Packer::add_medium(int i, const MediumDesc& md) {
  st_medium& m = st.media[i];
  std::memset(&m, 0, sizeof(m));
  std::string ctx_name = scene.path + ": " + md.json_path;
  m.type = md.type;
  m.phase_type = md.phase.type;
  m.g = float(md.phase.g);
  m.phase = f4(md.phase.blend[0], md.phase.blend[1], md.phase.blend[2], md.phase.blend[3]);
  m.majorant_scale = float(md.majorant_scale);
  m.minorant_scale = float(md.minorant_scale);
  // testing aids that keep the expectation but not a bounded variance (docs/scene-format.md)
  if (md.majorant_scale < 1)
    warn(fmt::format("{}/majorant_scale: {:g} < 1 under-estimates the majorant: where the density exceeds it the "
                     "null-collision weights turn negative and the image's variance can be unbounded (a testing aid "
                     "for the estimators, not for images)", ctx_name, md.majorant_scale));
  if (md.minorant_scale > 1 && st_tracker_decomposes(tracker))
    warn(fmt::format("{}/minorant_scale: {:g} > 1 over-estimates the minorant: the residual's weights turn negative "
                     "where the density is below it and the image's variance can be unbounded (a testing aid)",
                     ctx_name, md.minorant_scale));
  m.sigma_a = f4(md.sigma_a[0] * md.density_scale, md.sigma_a[1] * md.density_scale, md.sigma_a[2] * md.density_scale);
  m.sigma_s = f4(md.sigma_s[0] * md.density_scale, md.sigma_s[1] * md.density_scale, md.sigma_s[2] * md.density_scale);
  m.density_grid = ST_NO_GRID;
  m.emission_grid = ST_NO_GRID;
  m.blackbody_offset = ST_NO_GRID;
  m.velocity_grid[0] = ST_NO_GRID;
  if (md.emission.present) {
    const EmissionDesc& e = md.emission;
    Vec3 r = e.radiance;
    if (e.blackbody && e.temperature > 0) {
      // a constant temperature: its colour, exactly (no table)
      r = e.temperature > e.temperature_cutoff ? blackbody_linear_srgb(e.temperature, e.normalization) : Vec3{0, 0, 0};
      if (md.type == ST_MEDIUM_HOMOGENEOUS) check_blackbody_bounds(ctx_name, md, std::max({r[0], r[1], r[2]}), e.temperature, 1.0);
      if (md.type == ST_MEDIUM_HOMOGENEOUS && spectral && e.temperature > e.temperature_cutoff)
        check_blackbody_bounds(ctx_name, md, spectral_blackbody_peak(e.temperature, e.normalization), e.temperature, 1.0,
                               "spectral radiance");
    } else if (e.blackbody || e.ramp) {
      r = Vec3{1, 1, 1};  // scale x the temperature grid's or the ramp's colour (add_vdb_medium)
    }
    const double gain = emission_gain(md);
    if (!(gain <= kMaxRadiance))
      throw Error(fmt::format("{}/emission/model: scale / sigma_a = {} is more than {:g}", ctx_name, gain, kMaxRadiance));
    m.Le = f4(r[0] * gain, r[1] * gain, r[2] * gain);
    m.emissive = (m.Le.x > 0 || m.Le.y > 0 || m.Le.z > 0) ? 1 : 0;
  }
  m.maj_offset = uint32_t(maj_cells.size() / 2);


  if (md.type == ST_MEDIUM_HOMOGENEOUS) {
    const auto& lo = md.bounds[0];
    const auto& hi = md.bounds[1];
    for (int r = 0; r < 3; ++r) {
      double s = 1.0 / (hi[r] - lo[r]);
      float row[4] = {0, 0, 0, float(-lo[r] * s)};
      row[r] = float(s);
      m.world_to_index[r] = st_float4{row[0], row[1], row[2], row[3]};
    }
    m.maj_origin = f4(0, 0, 0, 1);
    m.maj_dims[0] = m.maj_dims[1] = m.maj_dims[2] = 1;
    maj_cells.push_back(1.0f);
    maj_cells.push_back(1.0f);
    check_float_limits(md, m, nullptr, ctx_name);
    media_boxes.push_back(Box3{lo, hi});
    // density 1 everywhere: a decomposing tracker's control is the whole medium (no lookup, with
    // bounding scales)
    chord_lookups += residual_majorant(1.0, 1.0, md.majorant_scale, md.minorant_scale, st_tracker_decomposes(tracker)) *
                     max_sigma_t(m) * mean_chord({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]});
    mean_sigma_maj += max_sigma_t(m);
    chord_depth += max_sigma_t(m) * mean_chord({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]});
    warn_long_paths(md, max_sigma_t(m) * mean_chord({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]}), ctx_name);
    return;
  }

  add_vdb_medium(m, md, ctx_name);
}

void Packer::add_vdb_medium(st_medium& m, const MediumDesc& md, const std::string& ctx_name) {
  GridData g = load_float_grid(md.file, md.grid, md.grid_index, ctx_name);
  media_boxes.push_back(medium_world_box(md, g));
  Mat4 i2w;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) i2w.m[r][c] = g.index_to_world[r][c];
  const Mat4 index_to_scene = user_transform(md.transform) * i2w;
  Mat4 w2i = inverse_affine(index_to_scene, ctx_name + "/transform");
  for (int r = 0; r < 3; ++r) m.world_to_index[r] = f4(w2i.m[r][0], w2i.m[r][1], w2i.m[r][2], w2i.m[r][3]);
  check_float_limits(md, m, &g, ctx_name);
  m.density_grid = upload_grid(ctx_name, g);
  const double color_max = md.color.present ? add_color_grid(m, md, g, ctx_name) : 0.0;  // sets sigma_t_maj, which the cost model uses
  const MotionReach motion = md.velocity.present ? add_velocity_grid(m, md, g, ctx_name) : MotionReach{};
  add_majorants(m, md, g, index_to_scene, motion);
  if (spectral && md.color.present) {
    // spectral mode (kernels/medium.h): the bound of the colour's spectrum per unit of sigma_s, 1
    // for an albedo; 2 max C for a scattering factor (its unbounded spectrum's scale), rounded up
    // as the rgb bound is
    const double k = md.color.mode == ST_COLOR_ALBEDO ? 1.0 : 2.0 * color_max * (1.0 + 1e-5);
    const float kf = md.color.mode == ST_COLOR_ALBEDO ? 1.0f : std::nextafter(float(k), std::numeric_limits<float>::infinity());
    m.sigma_t_maj = f4(kf, kf, kf);
  }
  add_emission(m, md, g, ctx_name);
}

void Packer::add_majorants(st_medium& m, const MediumDesc& md, const GridData& g, const Mat4& index_to_scene,
                           const MotionReach& motion) {
  const auto t_build = std::chrono::steady_clock::now();
  const int cell = opt.majorant_cell > 0 ? opt.majorant_cell : auto_majorant_cell(g);
  const std::array<double, 3>& reach = motion.reach;
  const std::array<int, 3> margin{int(std::ceil(reach[0])), int(std::ceil(reach[1])), int(std::ceil(reach[2]))};
  const int cell_used = majorant_cell_for(m, g, md.majorant_scale, cell);
  warn_slow_motion_bounds(g, cell_used, margin, reach, scene.path + ": " + md.json_path);
  MajorantGrid mg;
  try {
    mg = build_majorant_grid(g, cell_used, margin, motion.cell_reach);
  } catch (const Error& e) {  // a grid too wide for the cells: named by the scene's field
    const bool moving = margin[0] > 0 || margin[1] > 0 || margin[2] > 0;
    throw Error(fmt::format("{}: {}{}: {}", scene.path, md.json_path, moving ? "/velocity/scale" : "", e.what()));
  }
  m.maj_origin = f4(mg.origin[0], mg.origin[1], mg.origin[2], mg.cell);
  for (int a = 0; a < 3; ++a) m.maj_dims[a] = mg.dims[a];
  MajorantInfo info;
  info.cell = mg.cell;
  info.fine_cells = mg.dmax.size();
  // a colour medium's flights run at its extinction bound sigma_t_maj, and it has no control
  const bool color = m.color_mode != ST_COLOR_NONE;
  const double sigma_t = max_sigma_t(m);
  const bool decompose = st_tracker_decomposes(tracker) && !color;
  {
    // each fine cell's residual majorant, averaged, times the mean chord of the box in world units
    double sum = 0;
    for (size_t c = 0; c < mg.dmax.size(); ++c)
      sum += residual_majorant(mg.dmax[c], mg.dmin[c], md.majorant_scale, md.minorant_scale, decompose);
    const Mat4& w = index_to_scene;
    std::array<double, 3> side{};
    for (int a = 0; a < 3; ++a)
      side[size_t(a)] = double(mg.dims[size_t(a)]) * mg.cell *
                        std::sqrt(w.m[0][a] * w.m[0][a] + w.m[1][a] * w.m[1][a] + w.m[2][a] * w.m[2][a]);
    info.chord_lookups = mg.dmax.empty() ? 0.0 : sum / double(mg.dmax.size()) * sigma_t * mean_chord(side);
    chord_lookups += info.chord_lookups;
    double dmax_sum = 0;
    for (float d : mg.dmax) dmax_sum += double(d);
    const double mean_dmax = mg.dmax.empty() ? 0.0 : dmax_sum / double(mg.dmax.size());
    mean_sigma_maj += mean_dmax * sigma_t;
    chord_depth += mean_dmax * sigma_t * mean_chord(side);
    warn_long_paths(md, mean_dmax * sigma_t * mean_chord(side), scene.path + ": " + md.json_path);
  }
  const int B = opt.majorant_block;
  if (B > 1) {
    // the adaptive hierarchy: each block of B^3 cells walked whole or refined, by the cost model
    MajorantCostModel cost;
    cost.lookups_per_density = sigma_t * std::max(1.0, md.majorant_scale) * longest_voxel_edge(m);
    cost.decompose = decompose;
    cost.step_cost = opt.majorant_step_cost ? *opt.majorant_step_cost : auto_majorant_step_cost(tracker, !color);
    MajorantHierarchy h = build_majorant_hierarchy(mg, B, cost);
    m.maj_block = B;
    m.maj_coarse_offset = uint32_t(maj_cells.size() / 2);
    append_majorant_blocks(maj_cells, h.blocks);
    m.maj_offset = uint32_t(maj_cells.size() / 2);
    maj_cells.insert(maj_cells.end(), h.pool.begin(), h.pool.end());
    info.block = B;
    info.step_cost = cost.step_cost;
    info.blocks_empty = h.blocks_empty;
    info.blocks_whole = h.blocks_whole;
    info.blocks_refined = h.blocks_refined;
    info.levels = h.levels;
    info.blocks_per_level = h.blocks_per_level;
    info.bytes = h.blocks.size() * sizeof(st_maj_block) + h.pool.size() * sizeof(float);
  } else {
    for (size_t c = 0; c < mg.dmax.size(); ++c) {
      maj_cells.push_back(mg.dmax[c]);
      maj_cells.push_back(mg.dmin[c]);
    }
    info.bytes = mg.dmax.size() * 2 * sizeof(float);
  }
  info.seconds_build = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_build).count();
  majorants.push_back(info);
}

void Packer::add_emission(st_medium& m, const MediumDesc& md, const GridData& g, const std::string& ctx_name) {
  const EmissionDesc& em = md.emission;
  auto same_transform = [&](const GridData& e, const std::string& field) {
    if (!same_index_to_world(e, g))
      throw Error(fmt::format("{}/emission/{}: grid '{}' has a different index-to-world transform than density "
                              "grid '{}'; both grids must share one transform",
                              ctx_name, field, e.name, md.grid));
  };
  if (em.blackbody && em.temperature > 0) {
    // add_medium set Le = scale x the colour (emissive: scale > 0)
    if (m.emissive) check_blackbody_bounds(ctx_name, md, std::max({m.Le.x, m.Le.y, m.Le.z}) / em.scale, em.temperature, g.value_max);
    if (m.emissive && spectral)
      check_blackbody_bounds(ctx_name, md, spectral_blackbody_peak(em.temperature, em.normalization), em.temperature,
                             g.value_max, "spectral radiance");
  } else if (em.blackbody && m.emissive) {
    const GridData t = add_temperature_grid(m, md, g, ctx_name);
    if (m.emissive) {
      same_transform(t, "temperature_grid");
      m.emission_grid = upload_grid(ctx_name, t);
    }
  } else if (em.ramp && m.emissive) {
    if (spectral)
      throw Error(fmt::format("{}/emission/type: a ramp is RGB only; spectral mode (render.color) cannot render it",
                              ctx_name));
    GridData e = load_float_grid(md.file, em.grid, -1, ctx_name + "/emission/grid");
    same_transform(e, "grid");
    MediumDesc bounds = md;  // the bounds of the ramp's brightest colour
    const double peak = pack_emission_ramp(m, em.stops, e.value_min, e.value_max, grid_words);
    bounds.emission.radiance = {peak, peak, peak};
    check_emission_bounds(ctx_name, bounds, g.value_max, 1.0);
    m.emission_grid = upload_grid(ctx_name, e);
  } else if (em.grid.empty()) {
    check_emission_bounds(ctx_name, md, g.value_max, 1.0);
  } else if (em.present && m.emissive) {
    GridData e = load_float_grid(md.file, em.grid, -1, ctx_name + "/emission/grid");
    check_emission_bounds(ctx_name, md, g.value_max, e.value_max);
    same_transform(e, "grid");
    m.emission_grid = upload_grid(ctx_name, e);
  }
}

// The file's temperature grid (emission.temperature_grid, else the first of "temperature",
// "heat", "flame"), the temperatures its values map to, and the blackbody colour table the
// kernels interpolate (kernels/medium.h blackbody_rgb), appended to the grid buffer.
GridData Packer::add_temperature_grid(st_medium& m, const MediumDesc& md, const GridData& density,
                                      const std::string& ctx_name) {
  EmissionDesc e = md.emission;
  const std::string ctx = ctx_name + "/emission/temperature_grid";
  std::string name = e.temperature_grid;
  if (name.empty() && !e.temperature_grid_choices.empty()) {  // a preset's fire grids
    const std::vector<std::string> grids = list_grids(md.file);
    for (const auto& [candidate, scale] : e.temperature_grid_choices) {
      if (!grid_listed(grids, candidate)) continue;
      name = candidate;
      e.temperature_scale = scale;
      break;
    }
    if (name.empty()) {
      warn(fmt::format("{}/preset: {} has none of the preset's fire grids: the medium does not emit", ctx_name, md.file));
      m.emissive = 0;
      return GridData{};
    }
  }
  if (name.empty()) {
    const std::vector<std::string> grids = list_grids(md.file);
    for (const std::string& candidate : default_temperature_grids())
      if (name.empty() && grid_listed(grids, candidate)) name = candidate;
    if (name.empty()) {
      std::string all;
      for (const std::string& entry : grids) all += (all.empty() ? "" : ", ") + entry;
      throw Error(fmt::format("{}: {} has no grid named temperature, heat or flame (its grids: {}); name the "
                              "temperature grid with emission.temperature_grid",
                              ctx, md.file, all));
    }
  }
  GridData t = load_float_grid(md.file, name, -1, ctx);
  // the values the kernels can read: the active values and the background 0 (trilinear blends stay within)
  const double v_lo = std::min(double(t.value_min), 0.0), v_hi = std::max(double(t.value_max), 0.0);
  const double T_hi = std::max((v_lo - e.temperature_offset) * e.temperature_scale,
                               (v_hi - e.temperature_offset) * e.temperature_scale);
  if (!(T_hi <= kMaxTemperature))
    throw Error(fmt::format("{}: grid '{}' (values {} .. {}) maps to temperatures up to {} K with temperature_offset {} "
                            "and temperature_scale {}; at most {:g} K",
                            ctx, name, t.value_min, t.value_max, T_hi, e.temperature_offset, e.temperature_scale,
                            kMaxTemperature));
  // T = value * a + b on the device: a and b in double, then float (their range checked)
  const double ta = e.temperature_scale, tb = -e.temperature_offset * e.temperature_scale;
  if (!(std::abs(ta) < 1e30) || !(std::abs(tb) < 1e30))
    throw Error(fmt::format("{}: temperature_scale ({}) or temperature_offset x temperature_scale ({}) is not below "
                            "1e30, the bound on the float coefficients of T = value x temperature_scale - "
                            "temperature_offset x temperature_scale in the kernels", ctx, ta, -tb));
  if (!(T_hi > e.temperature_cutoff)) {
    warn(fmt::format("{}: grid '{}' maps to temperatures of at most {:g} K, at or below the cutoff {:g} K: the medium "
                     "does not emit", ctx, name, T_hi, e.temperature_cutoff));
    m.emissive = 0;
    return t;
  }
  const BlackbodyTable table = make_blackbody_table(e.temperature_cutoff, T_hi, e.normalization, kBlackbodyEntries);
  check_blackbody_bounds(ctx_name, md, table.max_value, T_hi, density.value_max);
  if (spectral)
    check_blackbody_bounds(ctx_name, md, film_emission_scale() * table.spectrum_max, T_hi, density.value_max,
                           "spectral radiance");
  m.temperature = f4(ta, tb, e.temperature_cutoff, kBlackbodyWarpA);
  m.blackbody_table = f4(table.warp_first, table.entries_per_warp, table.entries - 1, kBlackbodyWarpB);
  m.blackbody_offset = uint32_t(grid_words.size());
  grid_words.resize(grid_words.size() + table.rgbn.size());
  std::memcpy(grid_words.data() + m.blackbody_offset, table.rgbn.data(), table.rgbn.size() * sizeof(float));
  return t;
}

// A medium's colour grid (medium.h): three component grids in the density grid's index space, and
// the extinction bound per unit density that the majorants use.
double Packer::add_color_grid(st_medium& m, const MediumDesc& md, const GridData& density, const std::string& ctx_name) {
  const std::string ctx = ctx_name + "/color";
  std::array<GridData, 3> c = load_color_grid(md.file, md.color.grid, ctx);
  if (!same_index_to_world(c[0], density))
    throw Error(fmt::format("{}/grid: grid '{}' has a different index-to-world transform than density grid "
                            "'{}'; both grids must share one transform (resample one onto the other)",
                            ctx, md.color.grid, md.grid));
  std::array<double, 3> cmax{};
  for (int k = 0; k < 3; ++k) cmax[size_t(k)] = c[size_t(k)].value_max;
  if (md.color.mode == ST_COLOR_ALBEDO) {
    for (int k = 0; k < 3; ++k)
      if (cmax[size_t(k)] > 1.0)
        throw Error(fmt::format("{}/grid: grid '{}' holds albedo {} in channel {} (max over the grid and its "
                                "background), above 1; an albedo lies in [0, 1] (use \"mode\": \"scattering\" "
                                "to scale sigma_s instead)",
                                ctx, md.color.grid, cmax[size_t(k)], "xyz"[k]));
  }
  m.color_mode = md.color.mode;
  for (int k = 0; k < 3; ++k) m.color_grid[k] = upload_grid(ctx, c[size_t(k)]);
  m.color_grid[3] = ST_NO_GRID;
  // An upper bound of sigma_t per unit density, rounded up (the interpolated colour is a convex
  // combination of voxel values, up to a few ulps of rounding: 1e-5 relative covers it).
  const float sa[3] = {m.sigma_a.x, m.sigma_a.y, m.sigma_a.z}, ss[3] = {m.sigma_s.x, m.sigma_s.y, m.sigma_s.z};
  float bound[3];
  for (int k = 0; k < 3; ++k) {
    const double scale = md.color.mode == ST_COLOR_ALBEDO ? 1.0 : cmax[size_t(k)] * (1.0 + 1e-5);
    const double b = double(sa[k]) + double(ss[k]) * scale;
    bound[k] = std::nextafter(float(b), std::numeric_limits<float>::infinity());
    if (!std::isfinite(bound[k]))
      throw Error(fmt::format("{}/grid: grid '{}' scales sigma_s past the float range (max colour {})", ctx,
                              md.color.grid, cmax[size_t(k)]));
  }
  m.sigma_t_maj = f4(bound[0], bound[1], bound[2]);
  return std::max({cmax[0], cmax[1], cmax[2]});
}

uint32_t Packer::upload_grid(const std::string& ctx_name, const GridData& g) {
  uint32_t offset = uint32_t(grid_words.size());
  size_t bytes = g.handle.size();
  size_t words = (bytes + 7) / 8 * 2;
  grid_words.resize(grid_words.size() + words, 0u);
  std::memcpy(grid_words.data() + offset, g.handle.data(), bytes);
  if (grid_words.size() > (size_t(1) << 30))
    throw Error(ctx_name + ": volumes exceed 4 GiB of NanoVDB data, which 32-bit addressing cannot reach");
  return offset;
}

}  // namespace packing
}  // namespace spectrack
