// packer.h: the scene compiler's parts, shared by its files: scene_pack.cpp (pack_scene and the
// feature mask), pack_media.cpp (transforms, grids, majorants, emission bounds), pack_lights.cpp
// (lights, environment maps and their CDFs, light selection) and pack_camera.cpp (the camera).
// Internal to src/scene: pack_scene (scene_pack.h) is the interface.
#pragma once
#include <array>
#include <string>
#include <vector>

#include "scene/scene_pack.h"
#include "volume/volume.h"
#include "scene/framing.h"

namespace spectrack {
namespace packing {

// Entries of a blackbody colour table (kernels/medium.h blackbody_rgb, src/color/blackbody.h): 16384
// keep linear interpolation within ~1e-4 of the integral from 100 K to 1e9 K, at 256 KiB.
constexpr int kBlackbodyEntries = 16384;
static_assert(ST_BLACKBODY_T_FLOOR == kBlackbodyTableFloor, "kernels/types.h and src/color/blackbody.h: one floor");
// Scattering events per path above which a medium with unlimited max_depth is warned of (Packer::
// warn_long_paths): a million is seconds per path on a CPU core.
constexpr double kLongPathEvents = 1e6;
// Reads (voxels, or 8^3 leaves past kExactMotionBoundReads) of a moving medium's majorant bounds
// above which its load is warned of (a minute or so on a CPU core).
constexpr double kSlowMotionBoundVisits = 3e10;
// The same for leaf reads, counted over every cell of the box (the build reads only the cells
// that meet the tree): Blender's smoke frame moving up to 115 / 310 voxels counts 5e10 / 1e13
// and loads in 1.2 / 14 s on the 2-core VM.
constexpr double kSlowMotionLeafReads = 1e14;
// Warns where a moving medium's majorant bounds (cells of `cell` voxels over grid g, widened by
// `margin`, each reading its voxels within `reach`) would take minutes (pack_warnings.cpp).
void warn_slow_motion_bounds(const GridData& g, int cell, const std::array<int, 3>& margin,
                             const std::array<double, 3>& reach, const std::string& ctx_name);

// The emission bounds (scene/radiance.h) of a blackbody medium whose brightest colour component
// up to T_hi kelvin, before `scale`, is `peak` (`what`: "colour"; spectral mode checks its
// brightest spectral radiance as the film reads it as well).
void check_blackbody_bounds(const std::string& ctx, const MediumDesc& md, double peak, double T_hi, double density_max,
                            const char* what = "colour");

// The brightest spectral radiance of a blackbody at T as the film reads it, before `scale`
// (kernels/medium.h blackbody_spectral_Le; temperatures below the table's floor emit as the floor).
double spectral_blackbody_peak(double T, BlackbodyNorm norm);

inline st_float4 f4(double x, double y, double z, double w = 0) { return st_float4{float(x), float(y), float(z), float(w)}; }
inline st_float4 f4(const Vec3& v, double w = 0) { return f4(v[0], v[1], v[2], w); }

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

Mat4 inverse_affine(const Mat4& a, const std::string& what);
// The mean length of the chords of a box with sides a over uniformly random lines crossing it
// (Cauchy: 4 V / S).
double mean_chord(const std::array<double, 3>& a);
// The residual majorant of a majorant cell with bounds (dmax, dmin), per unit of sigma_t, as the
// walk's segments take it (kernels/walker.h tracker_segment); without decomposition the majorant.
double residual_majorant(double dmax, double dmin, double majorant_scale, double minorant_scale, bool decompose);
// The largest channel's extinction per unit density (a colour medium's: its bound sigma_t_maj, at
// which its flights run): the gray rate a shadow ray's lookups scale with.
double max_sigma_t(const st_medium& m);
// scale, then rotations about x, y, z, then translate (docs/scene-format.md, `transform`)
Mat4 user_transform(const TransformDesc& t);
// The hierarchy's automatic step cost (docs/majorant-hierarchy.md, bench/RESULTS.md "Adaptive
// majorant hierarchy"): 0.6 density lookups per DDA step, measured on PoCL, where the render time
// stays level while lookups fall; 2 for spectral trackers that decompose, whose variance grows by
// about 10% with the tighter control of finer levels (media with a control: not colour media) (the control's per-channel collision weights
// replace the residual's history-aware probabilities), which the lookup-only model does not see.
double auto_majorant_step_cost(int tracker, bool has_control);
// Whether two grids share one index-to-world map (to 1e-6 relative).
bool same_index_to_world(const GridData& a, const GridData& b);
Vec3 cross(const Vec3& a, const Vec3& b);

// How far a moving medium's lookups reach (motion blur, pack_velocity.cpp): reach[a] bounds the
// index displacement along axis a over the whole grid (its box grows by that); cell_reach bounds
// it per majorant cell (build_majorant_grid), empty for a still medium.
struct MotionReach {
  std::array<double, 3> reach{0, 0, 0};
  CellReach cell_reach;
};

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
  uint32_t camera_features = 0;       // st_feature bits of the lens and the shutter (pack_camera.cpp)
  double shutter_reach = 0;           // the largest |time| of the shutter (s; 0: none): motion blur's reach
  bool stochastic_lookup = false;     // one-voxel lookups (st_lookup_mode): a moving cell's bounds in whole voxels
  // Each light's power up to the common factor pi r^2 of pbrt-v4's Light::Phi (r: the scene
  // radius): the mean over channels of the irradiance a directional light gives, or 4 pi times the
  // mean radiance of an environment over the sphere.
  std::array<double, ST_MAX_LIGHTS> light_power = {};
  // a local light's nee_strength: its mean intensity (kernels/light.h light_contribution)
  std::array<double, ST_MAX_LIGHTS> local_strength = {};
  // density lookups of a shadow ray crossing every medium along its box's mean chord (the sum of
  // MajorantInfo::chord_lookups, homogeneous media included): light sampling "auto"
  double chord_lookups = 0;
  // equi-angular sampling (kernels/equiangular.h): the media's mean gray majorant extinction summed
  // over media (1/length), and its optical depth along the mean chord of each medium's box, summed
  double mean_sigma_maj = 0, chord_depth = 0;

  void add_medium(int i, const MediumDesc& md);
  void add_vdb_medium(st_medium& m, const MediumDesc& md, const std::string& ctx_name);
  // Warns where a medium's paths would take about a million scattering events or more (optical
  // depth tau across it, albedo near 1) and render.max_depth leaves them unlimited.
  void warn_long_paths(const MediumDesc& md, double tau, const std::string& ctx_name) const;
  // the majorant grid (and hierarchy) of a VDB medium, its MajorantInfo and chord lookups; motion:
  // the index displacement its lookups reach (motion blur), which grows its cells
  void add_majorants(st_medium& m, const MediumDesc& md, const GridData& g, const Mat4& index_to_scene,
                     const MotionReach& motion);
  // a moving medium's velocity grid (pack_velocity.cpp); returns the reach of its lookups (none
  // when it does not move during the shutter, and then uploads nothing)
  MotionReach add_velocity_grid(st_medium& m, const MediumDesc& md, const GridData& density, const std::string& ctx_name);
  // a VDB medium's emission: blackbody bounds, temperature or emission grid
  void add_emission(st_medium& m, const MediumDesc& md, const GridData& g, const std::string& ctx_name);
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
  // st_scene::equiangular from the EquiangularMode asked for (auto: on in thin media)
  void set_equiangular(int requested);
  // the camera (framed), its thin lens and its shutter and motion (the settings' shutter)
  void set_camera(const RenderSettings& s);
  uint32_t scene_features() const;
};

}  // namespace packing
}  // namespace spectrack
