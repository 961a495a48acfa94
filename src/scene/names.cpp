// names.cpp: the user-facing names of the tracker and spectral-scheme enums of kernels/types.h,
// and of the blackbody normalisations (color/blackbody.h).
//
// Design: the names come from the enums' own tables in kernels/types.h (ST_TRACKERS, ST_SCHEMES),
// so an enum value cannot lack a name. The scene loader, the CLI flags and the EXR metadata all go
// through these functions; nothing else spells the names.
#include <array>
#include <iterator>
#include <string>
#include <utility>
#include <vector>

#include "scene/scene.h"

namespace spectrack {
namespace {

#define ST_X_TRACKER_NAME(E, name, ch, achromatic, scheme, decomposes, absorption) name,
#define ST_X_SCHEME_NAME(E, name) name,
#define ST_X_ABSORPTION_NAME(E, name) name,
#define ST_X_LIGHT_SAMPLING_NAME(E, name) name,
#define ST_X_TRANSMITTANCE_NAME(E, name) name,
#define ST_X_LOOKUP_NAME(E, name) name,
#define ST_X_AOV_NAME(E, name) name,
#define ST_X_FILM_COLOR_NAME(E, name) name,
#define ST_X_WAVELENGTH_SAMPLING_NAME(E, name) name,
#define ST_X_GROUND_NAME(E, name) name,
const char* const kTrackerNames[] = {ST_TRACKERS(ST_X_TRACKER_NAME)};
const char* const kSchemeNames[] = {ST_SCHEMES(ST_X_SCHEME_NAME)};
const char* const kAbsorptionNames[] = {ST_ABSORPTIONS(ST_X_ABSORPTION_NAME)};
const char* const kLightSamplingNames[] = {ST_LIGHT_SAMPLINGS(ST_X_LIGHT_SAMPLING_NAME)};
const char* const kTransmittanceNames[] = {ST_TRANSMITTANCES(ST_X_TRANSMITTANCE_NAME)};
const char* const kLookupNames[] = {ST_LOOKUPS(ST_X_LOOKUP_NAME)};
const char* const kAovNames[] = {ST_AOVS(ST_X_AOV_NAME)};
const char* const kFilmColorNames[] = {ST_FILM_COLORS(ST_X_FILM_COLOR_NAME)};
const char* const kWavelengthSamplingNames[] = {ST_WAVELENGTH_SAMPLINGS(ST_X_WAVELENGTH_SAMPLING_NAME)};
const char* const kGroundModeNames[] = {ST_GROUND_MODES(ST_X_GROUND_NAME)};
static_assert(sizeof(kGroundModeNames) / sizeof(kGroundModeNames[0]) == ST_GROUND_MODE_COUNT, "ground mode names");
static_assert(sizeof(kFilmColorNames) / sizeof(kFilmColorNames[0]) == ST_FILM_COLOR_COUNT, "film colour names");
static_assert(sizeof(kWavelengthSamplingNames) / sizeof(kWavelengthSamplingNames[0]) == ST_WAVELENGTH_SAMPLING_COUNT,
              "wavelength sampling names");
static_assert(sizeof(kAovNames) / sizeof(kAovNames[0]) == ST_AOV_COUNT, "aov names");
static_assert(sizeof(kLookupNames) / sizeof(kLookupNames[0]) == ST_LOOKUP_COUNT, "lookup names");
static_assert(sizeof(kTransmittanceNames) / sizeof(kTransmittanceNames[0]) == ST_TRANSMITTANCE_COUNT, "transmittance names");
static_assert(sizeof(kLightSamplingNames) / sizeof(kLightSamplingNames[0]) == ST_LIGHT_SAMPLING_COUNT, "light sampling names");
static_assert(sizeof(kAbsorptionNames) / sizeof(kAbsorptionNames[0]) == ST_ABSORPTION_COUNT, "absorption names");
static_assert(sizeof(kTrackerNames) / sizeof(kTrackerNames[0]) == ST_TRACKER_COUNT, "tracker names");
static_assert(sizeof(kSchemeNames) / sizeof(kSchemeNames[0]) == ST_SCHEME_COUNT, "scheme names");

template <int N>
const char* name_of(const char* const (&table)[N], int value) {
  return value >= 0 && value < N ? table[value] : "unknown";
}

template <int N>
int value_of(const char* const (&table)[N], const std::string& name) {
  for (int i = 0; i < N; ++i)
    if (name == table[i]) return i;
  return -1;
}

template <int N>
std::string list_of(const char* const (&table)[N]) {
  std::string s;
  for (int i = 0; i < N; ++i) s += (i ? ", " : "") + std::string(table[i]);
  return s;
}

}  // namespace

const char* tracker_name(int tracker) { return name_of(kTrackerNames, tracker); }
const char* scheme_name(int scheme) { return name_of(kSchemeNames, scheme); }
int tracker_from_name(const std::string& name) { return value_of(kTrackerNames, name); }
int scheme_from_name(const std::string& name) { return value_of(kSchemeNames, name); }
std::string tracker_names() { return list_of(kTrackerNames); }
std::string scheme_names() { return list_of(kSchemeNames); }
std::vector<std::string> tracker_name_list() { return {std::begin(kTrackerNames), std::end(kTrackerNames)}; }
std::vector<std::string> scheme_name_list() { return {std::begin(kSchemeNames), std::end(kSchemeNames)}; }
const char* absorption_name(int absorption) { return name_of(kAbsorptionNames, absorption); }
int absorption_from_name(const std::string& name) { return value_of(kAbsorptionNames, name); }
std::string absorption_names() { return list_of(kAbsorptionNames); }
std::vector<std::string> absorption_name_list() { return {std::begin(kAbsorptionNames), std::end(kAbsorptionNames)}; }
const char* light_sampling_name(int mode) { return name_of(kLightSamplingNames, mode); }
int light_sampling_from_name(const std::string& name) { return value_of(kLightSamplingNames, name); }
std::string light_sampling_names() { return list_of(kLightSamplingNames); }
std::vector<std::string> light_sampling_name_list() {
  return {std::begin(kLightSamplingNames), std::end(kLightSamplingNames)};
}
const char* transmittance_name(int mode) { return name_of(kTransmittanceNames, mode); }
int transmittance_from_name(const std::string& name) { return value_of(kTransmittanceNames, name); }
std::string transmittance_names() { return list_of(kTransmittanceNames); }
std::vector<std::string> transmittance_name_list() {
  return {std::begin(kTransmittanceNames), std::end(kTransmittanceNames)};
}
const char* lookup_name(int mode) { return name_of(kLookupNames, mode); }
int lookup_from_name(const std::string& name) { return value_of(kLookupNames, name); }
std::string lookup_names() { return list_of(kLookupNames); }
std::vector<std::string> lookup_name_list() { return {std::begin(kLookupNames), std::end(kLookupNames)}; }
const char* wavelength_sampling_name(int mode) { return name_of(kWavelengthSamplingNames, mode); }
int wavelength_sampling_from_name(const std::string& name) { return value_of(kWavelengthSamplingNames, name); }
std::string wavelength_sampling_names() { return list_of(kWavelengthSamplingNames); }
std::vector<std::string> wavelength_sampling_name_list() {
  return {std::begin(kWavelengthSamplingNames), std::end(kWavelengthSamplingNames)};
}
const char* film_color_name(int mode) { return name_of(kFilmColorNames, mode); }
const char* ground_mode_name(int mode) { return name_of(kGroundModeNames, mode); }
int ground_mode_from_name(const std::string& name) { return value_of(kGroundModeNames, name); }
std::string ground_mode_names() { return list_of(kGroundModeNames); }
int film_color_from_name(const std::string& name) { return value_of(kFilmColorNames, name); }
std::string film_color_names() { return list_of(kFilmColorNames); }
const char* aov_name(int index) { return name_of(kAovNames, index); }
int aov_from_name(const std::string& name) { return value_of(kAovNames, name); }
std::string aov_names() { return list_of(kAovNames); }
std::vector<std::string> aov_name_list() { return {std::begin(kAovNames), std::end(kAovNames)}; }
const std::vector<std::string>& aov_exr_channels(int index) {
  static const std::vector<std::vector<std::string>> table = [] {
    std::vector<std::vector<std::string>> t;
    for (int k = 0; k < ST_AOV_COUNT; ++k) {
      const std::string n = kAovNames[k];
      if (k == ST_AOV_INDEX_ALPHA) t.push_back({"A", "AR", "AG", "AB"});
      else if (k == ST_AOV_INDEX_DEPTH) t.push_back({n + ".Z"});
      else if (k == ST_AOV_INDEX_SHADOW)  // the ratio, then the mean unshadowed estimate (its weight)
        t.push_back({n + ".R", n + ".G", n + ".B", "unshadowed.R", "unshadowed.G", "unshadowed.B"});
      else t.push_back({n + ".R", n + ".G", n + ".B"});
    }
    return t;
  }();
  static const std::vector<std::string> none;
  return index >= 0 && index < ST_AOV_COUNT ? table[size_t(index)] : none;
}
namespace {
// OpenEXR's compressions as OpenImageIO names them (its "compression" attribute), and whether
// 32-bit float channels come back bit for bit: pxr24 rounds floats to 24 bits and the DWA
// compressions quantise R, G, B; b44 and b44a compress half channels only (floats verbatim).
struct ExrCompression {
  const char* name;
  bool floats_exact;
};
constexpr std::array<ExrCompression, 10> kExrCompressions = {{{"none", true}, {"rle", true}, {"zips", true},
                                                              {"zip", true}, {"piz", true}, {"pxr24", false},
                                                              {"b44", true}, {"b44a", true}, {"dwaa", false},
                                                              {"dwab", false}}};
}  // namespace
const std::vector<std::string>& exr_compressions() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> n;
    for (const ExrCompression& c : kExrCompressions) n.push_back(c.name);
    return n;
  }();
  return names;
}
bool exr_compression_keeps_floats(const std::string& name) {
  for (const ExrCompression& c : kExrCompressions)
    if (name == c.name) return c.floats_exact;
  return true;  // a compression OpenEXR added later: not known to be lossy
}
bool tracker_uses_scheme(int tracker) { return st_tracker_uses_scheme(tracker) != 0; }


// Blackbody normalisations (color/blackbody.h declares them; defined here so that the scene loader
// and its fuzzing harness need no colour science).
namespace {
constexpr std::array<std::pair<BlackbodyNorm, const char*>, 3> kNormNames = {
    {{BlackbodyNorm::Peak, "peak"}, {BlackbodyNorm::Luminance, "luminance"}, {BlackbodyNorm::None, "none"}}};
}  // namespace

const char* blackbody_norm_name(BlackbodyNorm n) {
  for (const auto& [k, name] : kNormNames)
    if (k == n) return name;
  return "?";
}

bool blackbody_norm_from_name(const std::string& name, BlackbodyNorm* n) {
  for (const auto& [k, v] : kNormNames)
    if (name == v) {
      *n = k;
      return true;
    }
  return false;
}

std::string blackbody_norm_names() {
  std::string s;
  for (const auto& [k, name] : kNormNames) s += (s.empty() ? "" : ", ") + std::string(name);
  return s;
}

}  // namespace spectrack
