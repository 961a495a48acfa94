// names.cpp: the user-facing names of the tracker and spectral-scheme enums of kernels/types.h.
//
// Design: one table per enum, indexed by the enum value and sized by its *_COUNT, so adding an
// enum value without a name fails to compile. The scene loader, the CLI flags and the EXR
// metadata all go through these functions; nothing else spells the names.
#include <string>

#include "scene/scene.h"

namespace spectrack {
namespace {

const char* const kTrackerNames[] = {"delta-per-channel", "delta", "spectral", "decomposition",
                                     "spectral-decomposition"};
const char* const kSchemeNames[] = {"max", "average", "history-max", "history-average"};
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

}  // namespace spectrack
