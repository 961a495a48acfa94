// scene_pack.cpp: see scene_pack.h. Transforms are composed in double precision (scale, then
// rotations about x, y, z, then translation: docs/scene-format.md, `transform`) and only the final world-to-index
// rows are rounded to float.
#include "render/scene_pack.h"
#include "render/spectral_pack.h"
#include "render/emission_ramp.h"

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
#include "volume/float_limits.h"
#include "render/media_bounds.h"
#include "render/memory_budget.h"
#include "scene/framing.h"
#include "volume/volume.h"

namespace spectrack {

namespace {

// Entries of a blackbody colour table (kernels/medium.h blackbody_rgb, src/color/blackbody.h): 16384
// keep linear interpolation within ~1e-4 of the integral from 100 K to 1e9 K, at 256 KiB.
constexpr int kBlackbodyEntries = 16384;
static_assert(ST_BLACKBODY_T_FLOOR == kBlackbodyTableFloor, "kernels/types.h and src/color/blackbody.h: one floor");

// The emission bounds (scene/radiance.h) of a blackbody medium whose brightest colour component
// up to T_hi kelvin, before `scale`, is `peak` (`what`: "colour"; spectral mode checks its
// brightest spectral radiance as the film reads it as well).
void check_blackbody_bounds(const std::string& ctx, const MediumDesc& md, double peak, double T_hi, double density_max,
                            const char* what = "colour") {
  const EmissionDesc& e = md.emission;
  const double le = peak * e.scale;
  const char* why = " (the kernels carry light in single-precision float: see README \"Limits\")";
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

st_float4 f4(double x, double y, double z, double w = 0) { return st_float4{float(x), float(y), float(z), float(w)}; }
st_float4 f4(const Vec3& v, double w = 0) { return f4(v[0], v[1], v[2], w); }

// 4x4 affine matrices in double precision, row-major, for the medium transforms.
struct Mat4 {
  double m[4][4] = {{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}, {0, 0, 0, 1}};
  Mat4 operator*(const Mat4& b) const {
    Mat4 r;
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) {
        r.m[i][j] = 0;
        for (int k = 0; k < 4; ++k) r.m[i][j] += m[i][k] * b.m[k][j];
      }
    return r;
  }
};

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
// walk's segments take it (majorant.h segments_current); without decomposition the majorant.
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

Vec3 normalize(Vec3 v) {
  double l = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
  return {v[0] / l, v[1] / l, v[2] / l};
}
Vec3 cross(const Vec3& a, const Vec3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}

bool achromatic(const Vec3& v) { return v[0] == v[1] && v[1] == v[2]; }

// The hierarchy's automatic step cost (docs/majorant-hierarchy.md, bench/RESULTS.md "Adaptive
// majorant hierarchy"): 0.6 density lookups per DDA step, measured on PoCL, where the render time
// stays level while lookups fall; 2 for spectral trackers that decompose, whose variance grows by
// about 10% with the tighter control of finer levels (media with a control: not colour media) (the control's per-channel collision weights
// replace the residual's history-aware probabilities), which the lookup-only model does not see.
double auto_majorant_step_cost(int tracker, bool has_control) {
  return (has_control && st_tracker_decomposes(tracker) && st_tracker_channels(tracker) == 1) ? 2.0 : 0.6;
}

// Fills a PackedScene; member names follow st_scene's buffers.
struct Packer {
  const SceneDesc& scene;
  const PackOptions& opt;
  st_scene& st;
  std::vector<uint32_t>& grid_words;
  std::vector<float>& maj_cells;
  std::vector<float>& env_data;
  std::vector<MajorantInfo>& majorants;
  int tracker = 0;                     // st_tracker: the majorant hierarchy's cost model
  bool spectral = false;               // spectral mode (make_spectral follows): its bounds are checked too
  std::vector<Box3> media_boxes = {};  // world boxes, for the camera's framing
  Vec3 camera_position = {};          // as placed (framing included), in double
  // Each light's power up to the common factor pi r^2 of pbrt-v4's Light::Phi (r: the scene
  // radius): the mean over channels of the irradiance a directional light gives, or 4 pi times the
  // mean radiance of an environment over the sphere.
  std::array<double, ST_MAX_LIGHTS> light_power = {};
  // density lookups of a shadow ray crossing every medium along its box's mean chord (the sum of
  // MajorantInfo::chord_lookups, homogeneous media included): light sampling "auto"
  double chord_lookups = 0;

  void add_medium(int i, const MediumDesc& md);
  void add_vdb_medium(st_medium& m, const MediumDesc& md, const std::string& ctx_name);
  // returns the colour's largest value over its channels, its voxels and its background
  double add_color_grid(st_medium& m, const MediumDesc& md, const GridData& density, const std::string& ctx_name);
  GridData add_temperature_grid(st_medium& m, const MediumDesc& md, const GridData& density, const std::string& ctx_name);
  uint32_t upload_grid(const std::string& ctx_name, const GridData& g);
  void add_light(int i, const LightDesc& ld);
  // both return the map's mean radiance over the sphere (before its scale)
  double add_env_map(st_light& l, const LightDesc& ld);
  double add_env_cdf(st_light& l);
  void set_light_selection(int light_sampling);
  int resolve_light_sampling(int requested) const;
  void set_camera();
  uint32_t scene_features() const;
};

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
  m.sigma_a = f4(md.sigma_a[0] * md.density_scale, md.sigma_a[1] * md.density_scale, md.sigma_a[2] * md.density_scale);
  m.sigma_s = f4(md.sigma_s[0] * md.density_scale, md.sigma_s[1] * md.density_scale, md.sigma_s[2] * md.density_scale);
  m.density_grid = ST_NO_GRID;
  m.emission_grid = ST_NO_GRID;
  m.blackbody_offset = ST_NO_GRID;
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
  const auto t_build = std::chrono::steady_clock::now();
  const int cell = opt.majorant_cell > 0 ? opt.majorant_cell : auto_majorant_cell(g);
  MajorantGrid mg = build_majorant_grid(g, majorant_cell_for(m, g, md.majorant_scale, cell));
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
  }
  const int B = opt.majorant_block;
  if (B > 1) {
    // the adaptive hierarchy: each block of B^3 cells walked whole or refined, by the cost model
    MajorantCostModel cost;
    cost.lookups_per_density = sigma_t * std::max(1.0, md.majorant_scale) * longest_voxel_edge(m);
    cost.decompose = decompose;
    cost.step_cost = opt.majorant_step_cost >= 0 ? opt.majorant_step_cost : auto_majorant_step_cost(tracker, !color);
    MajorantHierarchy h = build_majorant_hierarchy(mg, B, cost);
    m.maj_block = B;
    m.maj_coarse_offset = uint32_t(maj_cells.size() / 2);
    maj_cells.insert(maj_cells.end(), h.blocks.begin(), h.blocks.end());
    m.maj_offset = uint32_t(maj_cells.size() / 2);
    maj_cells.insert(maj_cells.end(), h.pool.begin(), h.pool.end());
    info.block = B;
    info.blocks_empty = h.blocks_empty;
    info.blocks_whole = h.blocks_whole;
    info.blocks_refined = h.blocks_refined;
    info.levels = h.levels;
    info.blocks_per_level = h.blocks_per_level;
    info.bytes = (h.blocks.size() + h.pool.size()) * sizeof(float);
  } else {
    for (size_t c = 0; c < mg.dmax.size(); ++c) {
      maj_cells.push_back(mg.dmax[c]);
      maj_cells.push_back(mg.dmin[c]);
    }
    info.bytes = mg.dmax.size() * 2 * sizeof(float);
  }
  info.seconds_build = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_build).count();
  majorants.push_back(info);
  if (spectral && md.color.present) {
    // spectral mode (kernels/medium.h): the bound of the colour's spectrum per unit of sigma_s, 1
    // for an albedo; 2 max C for a scattering factor (its unbounded spectrum's scale), rounded up
    // as the rgb bound is
    const double k = md.color.mode == ST_COLOR_ALBEDO ? 1.0 : 2.0 * color_max * (1.0 + 1e-5);
    const float kf = md.color.mode == ST_COLOR_ALBEDO ? 1.0f : std::nextafter(float(k), std::numeric_limits<float>::infinity());
    m.sigma_t_maj = f4(kf, kf, kf);
  }
  const EmissionDesc& em = md.emission;
  auto same_transform = [&](const GridData& e, const std::string& field) {
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c)
        if (std::abs(e.index_to_world[r][c] - g.index_to_world[r][c]) > 1e-6 * (1 + std::abs(g.index_to_world[r][c])))
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
    GridData e = load_float_grid(md.file, em.grid, -1, ctx_name + "/emission");
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
      std::fprintf(stderr, "warning: %s/preset: %s has none of the preset's fire grids: the medium does not emit\n",
                   ctx_name.c_str(), md.file.c_str());
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
    std::fprintf(stderr, "warning: %s: grid '%s' maps to temperatures of at most %g K, at or below the cutoff %g K: "
                 "the medium does not emit\n", ctx.c_str(), name.c_str(), T_hi, e.temperature_cutoff);
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
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 4; ++k)
      if (std::abs(c[0].index_to_world[r][k] - density.index_to_world[r][k]) >
          1e-6 * (1 + std::abs(density.index_to_world[r][k])))
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

void Packer::add_light(int i, const LightDesc& ld) {
  st_light& l = st.lights[i];
  std::memset(&l, 0, sizeof(l));
  l.type = ld.type;
  auto mean = [](const Vec3& v) { return (v[0] + v[1] + v[2]) / 3.0; };
  if (ld.type == ST_LIGHT_DIRECTIONAL) {
    light_power[i] = mean(ld.irradiance);
    Vec3 d = normalize(ld.to_light);
    l.direction = f4(d);
    double half = ld.angle_deg * 0.5 * M_PI / 180.0;
    if (half <= 0) {
      l.is_delta = 1;
      l.radiance = f4(ld.irradiance);
      l.cos_max = 1.0f;
    } else {
      // a uniform disc of angular radius `half` gives irradiance E = L * pi * sin^2(half)
      double s2 = std::sin(half) * std::sin(half);
      double L = 1.0 / (M_PI * s2);
      l.radiance = f4(ld.irradiance[0] * L, ld.irradiance[1] * L, ld.irradiance[2] * L);
      l.cos_max = float(std::cos(half));
      l.pdf_cone = float(1.0 / (2.0 * M_PI * (1.0 - std::cos(half))));
    }
    return;
  }
  if (ld.map.empty()) {
    l.type = ST_LIGHT_ENV_UNIFORM;
    l.radiance = f4(ld.radiance);
    light_power[i] = 4.0 * M_PI * mean(ld.radiance);
    return;
  }
  light_power[i] = 4.0 * M_PI * ld.scale * add_env_map(l, ld);
}

// Light sampling "auto" (types.h): contribution where a shadow ray through the media takes
// kAutoContributionLookups lookups or more and there is a choice to make, else all.
int Packer::resolve_light_sampling(int requested) const {
  if (requested != ST_LIGHT_SAMPLING_AUTO) return requested;
  return st.n_lights > 1 && chord_lookups >= kAutoContributionLookups ? ST_LIGHT_SAMPLING_CONTRIBUTION
                                                                       : ST_LIGHT_SAMPLING_ALL;
}

// The probabilities with which next-event estimation picks each light (st_light::select_pmf):
// 1 for every light with light sampling "all" (one shadow ray each) or "contribution" (chosen per
// event: its MIS weights are all's, types.h) or a single light; 1 / n with "uniform"; with
// "power" in proportion to power (uniform if no light has any), a light without power never being
// picked. Every light's nee_strength: its mean irradiance (directional) or mean radiance over the
// sphere (environment), i.e. its power without the 4 pi of an environment.
void Packer::set_light_selection(int light_sampling) {
  double total = 0;
  for (int i = 0; i < st.n_lights; ++i) total += light_power[i];
  double acc = 0;
  for (int i = 0; i < st.n_lights; ++i) {
    st_light& l = st.lights[i];
    l.nee_strength = float(l.type == ST_LIGHT_DIRECTIONAL ? light_power[i] : light_power[i] / (4.0 * M_PI));
    if (light_sampling == ST_LIGHT_SAMPLING_ALL || light_sampling == ST_LIGHT_SAMPLING_CONTRIBUTION || st.n_lights == 1) {
      l.select_pmf = 1.0f;
      l.select_cdf = 1.0f;
      continue;
    }
    double pmf = light_sampling == ST_LIGHT_SAMPLING_POWER && total > 0 ? light_power[i] / total : 1.0 / st.n_lights;
    acc += pmf;
    l.select_pmf = float(pmf);
    l.select_cdf = i == st.n_lights - 1 ? 1.0f : float(acc);
  }
}

double Packer::add_env_map(st_light& l, const LightDesc& ld) {
  l.type = ST_LIGHT_ENV_MAP;
  RgbImage img;
  try {
    img = read_image(ld.map, ImageUse::kEnvironmentMap, [&](int w, int h) { check_env_map_memory(ld.map, w, h); });
  } catch (const Error& e) {
    throw Error(fmt::format("{}: {}/map: {}", scene.path, ld.json_path, e.what()));
  }
  check_env_map_bounds(scene.path + ": " + ld.json_path + "/map", ld.map, img.rgb, img.width, img.height, ld.scale);
  l.radiance = f4(ld.scale, ld.scale, ld.scale);
  const size_t W = size_t(img.width), H = size_t(img.height);
  l.map_width = img.width;
  l.map_height = img.height;
  l.map_offset = uint32_t(env_data.size());
  env_data.reserve(env_data.size() + W * H * 4 + (H + 1) + H * (W + 1));  // texels, then the CDFs
  for (size_t p = 0; p < W * H; ++p) {
    for (int c = 0; c < 3; ++c) env_data.push_back(img.rgb[p * 3 + c]);
    env_data.push_back(0.0f);
  }
  std::vector<float>().swap(img.rgb);  // the CDFs read the packed texels
  return add_env_cdf(l);
}

// sampling distribution: f(u, v) = max(rgb) * sin(theta), piecewise constant per texel; the
// marginal CDF over rows, then one conditional CDF per row, after the texels in env_data (read
// from there; f is evaluated again per texel rather than held)
double Packer::add_env_cdf(st_light& l) {
  const int W = l.map_width, H = l.map_height;
  auto texel = [&](int x, int y) { return &env_data[l.map_offset + (size_t(y) * W + x) * 4]; };
  auto f = [&](int x, int y, double s) {
    const float* px = texel(x, y);
    return std::max({px[0], px[1], px[2]}) * s;
  };
  double mean_radiance = 0;
  std::vector<double> row_sum(H, 0.0);
  for (int y = 0; y < H; ++y) {
    double s = std::sin(M_PI * (y + 0.5) / H);
    for (int x = 0; x < W; ++x) {
      const float* px = texel(x, y);
      // the texel's solid angle over the whole sphere's: (2 pi / W) (cos theta0 - cos theta1) / (4 pi)
      double omega = (std::cos(M_PI * y / H) - std::cos(M_PI * (y + 1.0) / H)) / (2.0 * W);
      mean_radiance += (double(px[0]) + px[1] + px[2]) / 3.0 * omega;
      row_sum[y] += f(x, y, s);
    }
  }
  double total = 0;
  for (double r : row_sum) total += r;
  l.cdf_offset = uint32_t(env_data.size());
  l.map_integral = float(total / (double(W) * H));
  double acc = 0;
  env_data.push_back(0.0f);
  for (int y = 0; y < H; ++y) {
    acc += row_sum[y];
    env_data.push_back(total > 0 ? float(acc / total) : float(y + 1) / H);
  }
  env_data[l.cdf_offset + H] = 1.0f;
  for (int y = 0; y < H; ++y) {
    const double s = std::sin(M_PI * (y + 0.5) / H);
    double a = 0;
    size_t base = env_data.size();
    env_data.push_back(0.0f);
    for (int x = 0; x < W; ++x) {
      a += f(x, y, s);
      env_data.push_back(row_sum[y] > 0 ? float(a / row_sum[y]) : float(x + 1) / W);
    }
    env_data[base + W] = 1.0f;
  }
  return mean_radiance;
}

void Packer::set_camera() {
  const CameraDesc c = frame_camera(scene.camera, scene.film.width, scene.film.height, media_boxes, scene.path + ": /camera");
  camera_position = c.position;
  st_camera& cam = st.camera;
  cam.type = c.type;
  cam.width = scene.film.width;
  cam.height = scene.film.height;
  Vec3 fwd = normalize({c.look_at[0] - c.position[0], c.look_at[1] - c.position[1], c.look_at[2] - c.position[2]});
  Vec3 right = normalize(cross(fwd, c.up));
  Vec3 up = cross(right, fwd);
  double shorter = std::min(cam.width, cam.height);
  double half = c.type == ST_CAMERA_ORTHOGRAPHIC ? 0.5 * c.height : std::tan(0.5 * c.fov_deg * M_PI / 180.0);
  double sx = half * cam.width / shorter, sy = half * cam.height / shorter;
  cam.position = f4(c.position);
  cam.forward = f4(fwd);
  cam.right = f4(right[0] * sx, right[1] * sx, right[2] * sx);
  cam.up = f4(up[0] * sy, up[1] * sy, up[2] * sy);
}

uint32_t Packer::scene_features() const {
  uint32_t f = 0;
  if (st.n_media > 1) f |= ST_FEATURE_MULTI_MEDIUM;
  for (int i = 0; i < st.n_media; ++i) {
    const st_medium& m = st.media[i];
    if (m.emissive) f |= ST_FEATURE_EMISSION;
    // exactly what the kernels see: the float coefficients
    bool gray = m.sigma_a.x == m.sigma_a.y && m.sigma_a.y == m.sigma_a.z && m.sigma_s.x == m.sigma_s.y &&
                m.sigma_s.y == m.sigma_s.z;
    if (!gray) f |= ST_FEATURE_CHROMATIC;
    if (m.color_mode != ST_COLOR_NONE) f |= ST_FEATURE_COLOR | ST_FEATURE_CHROMATIC;
    if (m.phase_type == ST_PHASE_HG) f |= ST_FEATURE_HG;
    if (m.phase_type == ST_PHASE_DRAINE_BLEND) f |= ST_FEATURE_PHASE_SET;
    if (m.type == ST_MEDIUM_VDB) f |= ST_FEATURE_VDB;
    if (m.maj_block > 0) f |= ST_FEATURE_COARSE_MAJORANT;
  }
  for (int i = 0; i < st.n_lights; ++i) {
    const st_light& l = st.lights[i];
    if (l.type == ST_LIGHT_ENV_MAP) f |= ST_FEATURE_ENV_MAP;
    if (l.type != ST_LIGHT_DIRECTIONAL || !l.is_delta) f |= ST_FEATURE_ESCAPE;
  }
  if (st_tracker_decomposes(st.tracker)) f |= ST_FEATURE_DECOMPOSITION;
  if (st.tracker == ST_TRACKER_SPECTRAL_MIS) f |= ST_FEATURE_SPECTRAL_MIS;
  if (st.lookup == ST_LOOKUP_STOCHASTIC && (f & ST_FEATURE_VDB)) f |= ST_FEATURE_STOCHASTIC_LOOKUP;
  if (st.result_layers > 1) f |= ST_FEATURE_AOV;
  return f;
}

}  // namespace

PackedScene pack_scene(const SceneDesc& scene, const RenderSettings& s, const PackOptions& options) {
  if (options.iteration_budget < 1) throw Error("iteration budget must be at least 1");
  if (options.majorant_cell < 0) throw Error("majorant cell must be 0 (automatic) or at least 1 voxel");
  if (options.majorant_block < 0) throw Error("majorant block must be 0 (one level) or at least 1 cell");
  if (!std::isfinite(options.majorant_step_cost))
    throw Error("majorant step cost must be a finite number (< 0: automatic)");
  PackedScene out;
  st_scene& st = out.st;
  std::memset(&st, 0, sizeof(st));
  Packer pk{scene, options, st, out.grid_words, out.maj_cells, out.env_data, out.majorants, s.tracker,
            s.color == ST_FILM_COLOR_SPECTRAL};
  st.n_media = int(scene.media.size());
  st.n_lights = int(scene.lights.size());
  for (int i = 0; i < st.n_media; ++i) pk.add_medium(i, scene.media[i]);
  for (int i = 0; i < st.n_lights; ++i) pk.add_light(i, scene.lights[i]);
  const int light_sampling = pk.resolve_light_sampling(s.light_sampling);
  pk.set_light_selection(light_sampling);
  pk.set_camera();
  check_coordinates(scene, st, pk.media_boxes, pk.camera_position);  // volume/float_limits.h
  st.tracker = s.tracker;
  st.scheme = s.scheme;
  st.absorption = s.absorption;
  st.light_sampling = light_sampling;
  st.transmittance = s.transmittance;
  st.march_spacing = float(s.march_spacing);
  st.pilot_spacing = float(s.pilot_spacing);
  st.lookup = s.lookup;
  st.aovs = int(s.aovs);
  st.result_layers = (s.aovs & (ST_AOV_BIT(ALBEDO) | ST_AOV_BIT(DEPTH)))  ? ST_RESULT_LAYERS_AUX
                     : (s.aovs & (ST_AOV_BIT(EMISSION) | ST_AOV_BIT(DIRECT) | ST_AOV_BIT(INDIRECT)))
                         ? ST_RESULT_LAYERS_PASSES
                         : (s.aovs & (ST_AOV_BIT(ALPHA) | ST_AOV_BIT(ENVIRONMENT))) ? ST_RESULT_LAYERS_AOV : 1;
  st.max_depth = scene.render.max_depth;
  st.seed = s.seed;
  st.n_channels_per_sample = s.channels_per_sample;
  st.iteration_budget = options.iteration_budget;
  st.batches_in_flight = 2;  // set per render
  st.pixel_x0 = s.window.x0;
  st.pixel_y0 = s.window.y0;
  st.window_width = s.window.width;
  st.window_height = s.window.height;
  for (auto& l : scene.lights) st.has_env |= (l.type != ST_LIGHT_DIRECTIONAL);
  for (auto& m : scene.media) st.chromatic |= !(achromatic(m.sigma_a) && achromatic(m.sigma_s));
  if (out.maj_cells.empty()) out.maj_cells = {0.0f, 0.0f};
  if (out.grid_words.empty()) out.grid_words = {0u, 0u};
  if (out.env_data.empty()) out.env_data = {0.0f};
  out.features = pk.scene_features();
  // spectral mode: the colours the kernels read become spectra, once everything above has been
  // derived from the rgb values (spectral_pack.h)
  if (s.color == ST_FILM_COLOR_SPECTRAL) make_spectral(scene, out);
  return out;
}

}  // namespace spectrack
