// scene.h: the scene description as loaded from a spectrack-scene/1 JSON file
// (docs/scene-format.md is the reference). load_scene() validates everything it can
// without touching VDB files: unknown fields, types, ranges, negative or NaN coefficients; every
// error is a spectrack::Error whose message names the scene file, the JSON path and the reason,
// e.g. "scene.json: /media/0/sigma_s: value -1 is negative". Relative paths are resolved against
// the scene file's folder. Enum values are the ones of kernels/types.h.
#pragma once
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "color/blackbody.h"
#include "color/sky.h"
#include "kernels/types.h"
#include "util/error.h"

namespace spectrack {

using Vec3 = std::array<double, 3>;
// The power of 2 that brings v's largest component within 2^+-500, where squaring it neither
// overflows nor vanishes; 0 for every other vector (and for a zero or non-finite one).
inline int vec3_rescale_exponent(const Vec3& v) {
  const double m = std::max({std::abs(v[0]), std::abs(v[1]), std::abs(v[2])});
  if (!(m > 0) || !std::isfinite(m)) return 0;
  const int e = std::ilogb(m);
  return e > 500 || e < -500 ? -e : 0;
}
// |v| and v / |v| for any finite v, a direction of length 1e200 or 1e-200 included (a user's
// to_light, up or spot axis): such a vector is first scaled by a power of 2, which is exact, so every
// other vector gives the plain formula's bits, sqrt(x x + y y + z z) and v / that.
inline double vec3_length(const Vec3& v) {
  const int k = vec3_rescale_exponent(v);
  const Vec3 s{std::ldexp(v[0], k), std::ldexp(v[1], k), std::ldexp(v[2], k)};
  return std::ldexp(std::sqrt(s[0] * s[0] + s[1] * s[1] + s[2] * s[2]), -k);
}
inline Vec3 unit_vector(const Vec3& v) {
  const int k = vec3_rescale_exponent(v);
  const Vec3 s{std::ldexp(v[0], k), std::ldexp(v[1], k), std::ldexp(v[2], k)};
  const double l = std::sqrt(s[0] * s[0] + s[1] * s[1] + s[2] * s[2]);
  return {s[0] / l, s[1] / l, s[2] / l};
}
// Whether a colour (sigma_a, sigma_s, ...) is gray: the same value in every channel.
inline bool achromatic(const Vec3& v) { return v[0] == v[1] && v[1] == v[2]; }

struct TransformDesc {
  Vec3 scale{1, 1, 1};       // "scale": a number or a triple
  Vec3 rotate_deg{0, 0, 0};  // rotations about x, then y, then z (degrees)
  Vec3 translate{0, 0, 0};
};

// The kernel's form of a phase function (scene/phase_models.h): isotropic, hg (g), or the Draine
// blend of "draine", "rayleigh", "hg2" and "mie" (g: lobe 1's g; blend: alpha1, g2, alpha2, w).
struct PhaseDesc {
  int type = ST_PHASE_ISOTROPIC;
  double g = 0.0;  // (-1, 1) for hg
  std::array<double, 4> blend{0, 0, 0, 0};
  std::string name = "isotropic";  // the scene's type
};

// A medium's emission (docs/scene-format.md "emission"): type "radiance", Le = radiance * scale
// (* the grid's value), or type "blackbody", Le = scale * the blackbody colour of T (linear sRGB,
// src/color/blackbody.h) with T = (temperature grid's value - temperature_offset) *
// temperature_scale, or a constant `temperature`; nothing emits where T <= temperature_cutoff.
// The grids a blackbody emission reads when it names none: the file's first of these.
inline const std::vector<std::string>& default_temperature_grids() {
  static const std::vector<std::string> names = {"temperature", "heat", "flame"};
  return names;
}

struct EmissionDesc {
  bool present = false;
  bool blackbody = false;
  // "ramp": Le = scale * the colour of `grid`'s value, linear between stops (value, [r, g, b]) of
  // increasing value, the end stops' colours beyond them (src/scene/emission_ramp.h)
  bool ramp = false;
  std::vector<std::pair<double, Vec3>> stops;
  // "model": "density" (the artists' model): the source term is density * Le, independent of
  // sigma_a (grey, > 0); false: the physical sigma_a * Le
  bool per_density = false;
  std::string grid;  // radiance: empty: Le = radiance * scale (constant where the medium is)
  Vec3 radiance{0, 0, 0};
  double scale = 1.0;
  // blackbody only
  std::string temperature_grid;  // empty: the file's first of "temperature", "heat", "flame"
  double temperature = -1;       // > 0: a constant temperature (K) instead of a grid
  double temperature_scale = 1.0;
  double temperature_offset = 0.0;
  double temperature_cutoff = 100.0;  // K, pbrt-v4's fixed cutoff
  BlackbodyNorm normalization = BlackbodyNorm::Peak;
  // a preset's (scene/presets.h) fire grids with their temperature_scale: the first the file has
  // is the temperature grid; none: no emission (a warning)
  std::vector<std::pair<std::string, double>> temperature_grid_choices;

  // Whether its colour is not 0 (before sigma_a or the density multiplies it): a radiance or a ramp
  // stop above 0, a blackbody above its cutoff (or of a grid), a scale above 0.
  bool colour_nonzero() const {
    auto positive = [](const Vec3& v) { return v[0] > 0 || v[1] > 0 || v[2] > 0; };
    if (!present || !(scale > 0)) return false;
    if (blackbody) return !(temperature > 0) || temperature > temperature_cutoff;
    if (ramp) {
      for (const auto& s : stops)
        if (positive(s.second)) return true;
      return false;
    }
    return positive(radiance);
  }
};

// A per-voxel colour (a vec3 grid of the medium's file, sharing the density grid's transform):
// "albedo": the single-scattering albedo per channel, in [0, 1] (sigma_t = sigma_a + sigma_s keeps
// its value; sigma_s = sigma_t * albedo, sigma_a = the rest); "scattering": a multiplier of sigma_s
// per channel, >= 0 (sigma_a unchanged). Kernels: medium.h medium_unit_coeffs.
struct ColorDesc {
  bool present = false;
  std::string grid = "Cd";
  int mode = ST_COLOR_ALBEDO;  // st_color_mode
};

// Motion blur from a velocity grid (a vec3s grid of the medium's file, sharing the density grid's
// transform; kernels/medium.h medium_lookup_index): the velocity in the file's world units per
// second is the grid's value times scale, times fps when the grid stores displacement per frame
// (fps > 0); voxels whose velocity is longer than outlier_threshold (world units per second, after
// scale and fps) read as 0.
struct VelocityDesc {
  bool present = false;
  std::string grid = "vel";
  double scale = 1.0;
  double fps = 0.0;  // 0: the grid holds world units per second
  double outlier_threshold = std::numeric_limits<double>::infinity();
};

struct MediumDesc {
  std::string name;
  std::string json_path;  // "/media/0", for messages
  int type = ST_MEDIUM_VDB;
  std::string file;       // vdb: absolute path (resolved against the scene folder)
  std::string grid = "density";
  int grid_index = -1;    // optional "grid_index": pick the n-th grid of that name (files with duplicates)
  double density_scale = 1.0;
  Vec3 sigma_s{1, 1, 1};
  Vec3 sigma_a{0, 0, 0};
  PhaseDesc phase;
  EmissionDesc emission;
  ColorDesc color;
  VelocityDesc velocity;
  TransformDesc transform;
  std::array<Vec3, 2> bounds{Vec3{-1, -1, -1}, Vec3{1, 1, 1}};  // homogeneous
  double majorant_scale = 1.0;  // testing aid: < 1 under-estimates (still unbiased)
  double minorant_scale = 1.0;  // testing aid: > 1 over-estimates (still unbiased)
  std::string preset;           // vdb: a preset's name (scene/presets.h), empty: none
};

// The factor of a medium's emitted radiance beyond its colour: scale, and with the "density"
// model 1 / sigma_a (grey), so that sigma_a * Le = density * scale * colour.
inline double emission_gain(const MediumDesc& m) {
  return m.emission.scale / (m.emission.per_density ? m.sigma_a[0] : 1.0);
}

// A physical sky (color/sky.h, docs/scene-format.md "sky"): its environment map is made when the
// scene is packed (scene/sky_light.h), its sun is a directional light of its own.
struct SkyDesc {
  double sun_elevation_deg = 15;  // above the horizon (the x-z plane), degrees
  double sun_azimuth_deg = 0;     // from -z towards +x (the environment map's centre is 0), degrees
  SkyAtmosphere atmosphere;
  double intensity = 1;           // multiplies the sky and the sun
  bool sun_disc = true;           // false: the sky alone
  double sun_angle_deg = 0.545;   // the sun's apparent diameter, degrees (0: a delta light)
  int resolution = 1024;          // the map's width (its height is half of it)
};

struct LightDesc {
  std::string json_path;
  int type = ST_LIGHT_ENV_UNIFORM;
  Vec3 radiance{1, 1, 1};  // environment (uniform); sphere: its surface's radiance
  std::string map;         // environment map (absolute path), empty if uniform
  double scale = 1.0;      // environment map multiplier
  double rotate_deg = 0.0; // environment map: its right-handed turn about +y, degrees (kernels/light.h)
  Vec3 to_light{0, 1, 0};  // directional, as given (not normalised)
  Vec3 irradiance{1, 1, 1};
  double angle_deg = 0.0;  // apparent diameter; 0 = delta light
  // point and spot lights (local: kernels/light.h)
  Vec3 position{0, 0, 0};
  Vec3 intensity{1, 1, 1};       // radiant intensity, W/sr
  Vec3 look_at{0, -1, 0};        // spot: the cone's axis points from position to look_at
  double cone_angle_deg = 30.0;  // spot: half angle of the cone, beyond which nothing is emitted
  double cone_delta_deg = 5.0;   // spot: width of the falloff (full intensity inside cone_angle - cone_delta)
  double radius = 0.0;           // sphere: world units, > 0 (position: its centre)
  // an environment map made from a sky model instead of a file (map empty, scale: the intensity);
  // a sky's sun is a directional light that follows it, with the same json_path
  std::optional<SkyDesc> sky;
};

// The ground (kernels/ground.h): the plane y = height, facing up, opaque; "albedo" its Lambertian
// reflectance in [0, 1] per channel; "mode" one of ST_GROUND_MODES (diffuse, shadow_catcher, holdout).
struct GroundDesc {
  bool present = false;
  double height = 0.0;     // world units
  Vec3 albedo{0.5, 0.5, 0.5};
  int mode = ST_GROUND_DIFFUSE;
};

struct CameraDesc {
  int type = ST_CAMERA_PERSPECTIVE;
  Vec3 position{0, 0, -4};
  Vec3 look_at{0, 0, 0};
  Vec3 up{0, 1, 0};
  double fov_deg = 40.0;  // perspective: full angle across the shorter image side
  double height = 2.0;    // orthographic: world units across the shorter image side
  // Framing (scene/framing.h), resolved when the scene is packed, once the media's boxes are known:
  bool look_at_media = false;  // "look_at": "media": aim at the centre of the union of the media's boxes
  bool position_auto = false;  // "position": "auto": along the default direction (0, 0, 1), (0, 1, 0) if up is z
  double fit = 0;              // > 0: move along the view direction (orthographic: set height) so every
                               // medium's box fills at most 1/fit of the frame; 0: no fitting
  // Thin lens (depth of field; pbrt-v4's lensradius and focaldistance): 0 is a pinhole.
  double aperture_radius = 0;  // world units
  double focus_distance = 0;   // world units along the view direction; 0: |look_at - position| once framed
  // Shutter [open, close], seconds relative to the frame; none: every path at time 0.
  std::optional<std::array<double, 2>> shutter;
  // Camera motion: position and look_at at shutter close (at open: position and look_at).
  std::optional<Vec3> position_close, look_at_close;
};

struct FilmDesc {
  int width = 512;
  int height = 512;
  int spp = 64;
  std::string output = "out.exr";  // resolved against the scene folder when relative
  std::optional<bool> alpha;       // film.alpha; not given: on for EXR outputs (the CLI decides, docs/aov.md)
  uint32_t aovs = 0;               // film.aovs: ST_AOV_BIT bits (alpha given here counts as film.alpha = true)
  bool half = false;               // film.half: 16-bit float EXR channels
  std::string compression = "zip"; // film.compression: an EXR compression (exr_compressions())
};

// Volume path guiding (docs/guiding.md): off, on, or auto (on for the scenes where guiding
// measures a gain: integrator/settings.h guiding_pays).
enum GuidingMode { kGuidingOff = 0, kGuidingOn = 1, kGuidingAuto = 2 };
inline int guiding_from_name(const std::string& n) { return n == "off" ? 0 : n == "on" ? 1 : n == "auto" ? 2 : -1; }
inline std::string guiding_names() { return "off, on, auto"; }
inline const char* guiding_name(int mode) { return mode == 0 ? "off" : mode == 1 ? "on" : "auto"; }
// Equi-angular sampling towards local lights (docs/equiangular.md): off, on, or auto (on where the
// media are thin: settings.h kAutoEquiangularDepth); the names and values are guiding's.
enum EquiangularMode { kEquiangularOff = kGuidingOff, kEquiangularOn = kGuidingOn, kEquiangularAuto = kGuidingAuto };

// The scene's `render` section. A field the file does not give is empty (std::nullopt) where the
// renderer's default depends on something else (the tracker's absorption) or lives in the
// settings (integrator/settings.h, kDefault...): resolve_settings() fills it.
struct RenderDesc {
  st_tracker tracker = ST_TRACKER_SPECTRAL_DECOMPOSITION;
  st_scheme scheme = ST_SCHEME_HISTORY_AVERAGE;
  bool scheme_set = false;  // the file gave spectral_scheme (a tracker that ignores it gets a warning)
  std::optional<st_absorption> absorption;            // none: the tracker's default (ST_TRACKERS)
  std::optional<st_light_sampling> light_sampling;    // none: kDefaultLightSampling (settings.h)
  std::optional<st_transmittance_mode> transmittance;  // none: kDefaultTransmittance (settings.h)
  std::optional<st_lookup_mode> lookup;               // none: kDefaultLookup (settings.h)
  st_film_color color = ST_FILM_COLOR_RGB;  // what a path's lanes carry (render.color)
  std::optional<st_wavelength_sampling> wavelength_sampling;  // spectral mode; none: kDefaultWavelengthSampling (settings.h)
  std::optional<int> max_depth;  // real scattering events a path may have; none: unlimited (the file's -1)
  uint32_t seed = 0;
  double time_limit = 0;  // seconds from the start of the command after which the render stops cleanly; 0: none
  double noise_target = 0;  // relative error of the image at which the render stops (integrator/noise.h); 0: none
  bool adaptive = false;    // adaptive sampling to noise_target (integrator/adaptive.h)
  std::optional<GuidingMode> guiding;  // none: auto
  std::optional<EquiangularMode> equiangular;  // none: kDefaultEquiangular (settings.h)
};

struct SceneDesc {
  std::string path;  // the scene file as given
  std::string dir;   // its folder
  CameraDesc camera;
  FilmDesc film;
  RenderDesc render;
  std::vector<LightDesc> lights;
  std::vector<MediumDesc> media;
  GroundDesc ground;
};

// Parses and validates a scene file. Throws spectrack::Error.
SceneDesc load_scene(const std::string& path);
// The text of a scene file, with load_scene's checks of the file itself (it exists, is not a folder,
// a USD stage or larger than kMaxSceneBytes); the Python module's load_file with overrides reads it.
std::string read_scene_text(const std::string& path);
// Same, from JSON text; `name` stands for the file in messages, `dir` resolves relative paths.
SceneDesc parse_scene(const std::string& json_text, const std::string& name, const std::string& dir);

// Names of the enums (the one table, used by the scene loader, the CLI and the EXR metadata).
const char* tracker_name(int tracker);
const char* scheme_name(int scheme);
// Return -1 for an unknown name.
int tracker_from_name(const std::string& name);
int scheme_from_name(const std::string& name);
// "a, b, c" lists for messages.
std::string tracker_names();
std::string scheme_names();
// The names in enum order (for the CLI's validators: the one table of names.cpp).
std::vector<std::string> tracker_name_list();
std::vector<std::string> scheme_name_list();
// Whether a tracker's event probabilities use the spectral scheme (spectral, spectral-decomposition);
// the others are analog: they use the channel maximum, which kernels/tracking.h calls max.
bool tracker_uses_scheme(int tracker);
// Names of the absorption modes (st_absorption): "event", "weight".
const char* absorption_name(int absorption);
int absorption_from_name(const std::string& name);  // -1 when unknown
std::string absorption_names();
std::vector<std::string> absorption_name_list();
// Names of the light sampling modes (st_light_sampling): "all", "uniform", "power".
const char* light_sampling_name(int mode);
int light_sampling_from_name(const std::string& name);  // -1 when unknown
std::string light_sampling_names();
std::vector<std::string> light_sampling_name_list();
// Names of the transmittance estimators (st_transmittance_mode): "ratio", "ray-marching".
const char* transmittance_name(int mode);
int transmittance_from_name(const std::string& name);  // -1 when unknown
std::string transmittance_names();
std::vector<std::string> transmittance_name_list();
// Names of the ground's modes (st_ground_mode): "diffuse", "shadow_catcher", "holdout".
const char* ground_mode_name(int mode);
int ground_mode_from_name(const std::string& name);  // -1 when unknown
std::string ground_mode_names();
// Names of the film colour modes (st_film_color): "rgb", "spectral".
const char* film_color_name(int mode);
int film_color_from_name(const std::string& name);  // -1 when unknown
std::string film_color_names();
// Names of the density lookup modes (st_lookup_mode): "trilinear", "stochastic".
const char* lookup_name(int mode);
int lookup_from_name(const std::string& name);  // -1 when unknown
std::string lookup_names();
std::vector<std::string> lookup_name_list();
// Names of the ways spectral mode draws wavelengths (st_wavelength_sampling): "independent", "stratified".
const char* wavelength_sampling_name(int mode);
int wavelength_sampling_from_name(const std::string& name);  // -1 when unknown
std::string wavelength_sampling_names();
std::vector<std::string> wavelength_sampling_name_list();
// Names of the film layers beyond the beauty (ST_AOVS, indices st_aov_index): "alpha",
// "environment", "variance", "emission", "direct", "indirect", "albedo", "depth".
const char* aov_name(int index);
int aov_from_name(const std::string& name);  // -1 when unknown
std::string aov_names();
std::vector<std::string> aov_name_list();
// The one table of the film layers' EXR channels (docs/aov.md), what a render writes, merge reads and
// read_image accepts: alpha "A", "AR", "AG", "AB"; depth "depth.Z"; shadow "shadow.R", ".G", ".B" and
// "unshadowed.R", ".G", ".B"; the others "<name>.R", ".G", ".B". The albedo and depth layers also
// write kCollisionChannel, their shared weight.
const std::vector<std::string>& aov_exr_channels(int index);
inline constexpr const char* kCollisionChannel = "collision.fraction";
// OpenEXR compressions (film.compression, --compression): none, rle, zips, zip, piz, pxr24, b44,
// b44a, dwaa, dwab. Those that change 32-bit floats (pxr24, dwaa, dwab; b44* only touch half
// channels, which a merge refuses anyway) lose the sums a merge needs: exr_compression_keeps_floats.
const std::vector<std::string>& exr_compressions();
bool exr_compression_keeps_floats(const std::string& name);  // name as exr_compressions() spells it

}  // namespace spectrack
