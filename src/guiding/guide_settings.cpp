// guide_settings.cpp: the guide's settings that the environment may change for measurements
// (guide_cache.h: SPECTRACK_GUIDE_DEPTH, _PRODUCT, _FULL_PATH, _ALPHA, _TRAINING, _TRAINING_KEEP,
// _RECORD_SAMPLES), and the fraction of a training pass's camera samples that make records.
//
// Design: each setting is read where a render resolves it, checked in full (a malformed value is
// an error naming the variable, never a silent default), and falls back to guide_cache.h's
// constant; none changes a render that does not set it.
#include <fmt/format.h>

#include <cctype>
#include <cstdlib>
#include <limits>
#include <string>

#include "guiding/guide_cache.h"
#include "util/error.h"
#include "util/option_text.h"

namespace spectrack {

int guide_depth_setting(int option) {
  if (option != 0) return option > 0 ? option : std::numeric_limits<int>::max();
  const char* e = std::getenv("SPECTRACK_GUIDE_DEPTH");
  if (!e || !*e) return kGuideDepth;
  char* end = nullptr;
  const long d = std::strtol(e, &end, 10);
  if (*end != '\0' || d < 0 || d > std::numeric_limits<int>::max())
    throw Error(fmt::format("SPECTRACK_GUIDE_DEPTH: '{}' is not a guided depth (0: every scatter event, or a "
                            "positive count of events)", e));
  return d > 0 ? int(d) : std::numeric_limits<int>::max();
}

namespace {
bool switch_setting(const char* name, bool fallback) {
  const char* e = std::getenv(name);
  if (!e || !*e) return fallback;
  if (std::string(e) != "0" && std::string(e) != "1") throw Error(fmt::format("{}: '{}' is not 0 or 1", name, e));
  return std::string(e) == "1";
}
}  // namespace

bool guide_phase_product_setting(int) { return switch_setting("SPECTRACK_GUIDE_PRODUCT", false); }
bool guide_full_path_setting(bool) { return switch_setting("SPECTRACK_GUIDE_FULL_PATH", false); }

float guide_alpha_setting() {
  const char* e = std::getenv("SPECTRACK_GUIDE_ALPHA");
  if (!e || !*e) return -1.0f;
  char* end = nullptr;
  const double a = std::strtod(e, &end);
  if (*end != '\0' || !(a >= 0 && a <= kGuideAlphaMax))
    throw Error(fmt::format("SPECTRACK_GUIDE_ALPHA: '{}' is not a selection probability in [0, {}]", e, kGuideAlphaMax));
  return float(a);
}

GuideTraining guide_training_setting() {
  GuideTraining t;
  const char* e = std::getenv("SPECTRACK_GUIDE_TRAINING");
  if (!e || !*e) {
    t.spp.assign(kGuideTrainingSpp, kGuideTrainingSpp + kGuideTrainingPasses);
  } else {
    for (const char* at = e;;) {  // numbers, each followed by a comma and another, or the end
      char* end = nullptr;
      const long n = std::isdigit(static_cast<unsigned char>(*at)) ? std::strtol(at, &end, 10) : 0;
      if (n < 1 || n > 65536 || (*end != ',' && *end != '\0') || t.spp.size() >= 16)
        throw Error(fmt::format("SPECTRACK_GUIDE_TRAINING: '{}' is not a list of at most 16 passes' samples per "
                                "pixel (1-65536, comma separated)", e));
      t.spp.push_back(int(n));
      if (*end == '\0') break;
      at = end + 1;
    }
  }
  t.keep = switch_setting("SPECTRACK_GUIDE_TRAINING_KEEP", true);
  return t;
}

int64_t guide_record_samples_setting() {
  const char* e = std::getenv("SPECTRACK_GUIDE_RECORD_SAMPLES");
  if (!e || !*e) return kGuideRecordSamples;
  int64_t v = 0;  // the command line's strict reader: digits only, no sign, space or overflow
  const std::string why = read_integer(e, 0, int64_t(1) << 40, &v);
  if (!why.empty())
    throw Error(fmt::format("SPECTRACK_GUIDE_RECORD_SAMPLES: '{}' is not a count of camera samples (0: every one; {})",
                            e, why));
  return v;
}

float guide_record_fraction(int64_t pixels, int spp, int64_t budget) {
  const double samples = double(pixels) * double(spp);
  if (budget == 0 || samples <= double(budget)) return 1.0f;
  return float(double(budget) / samples);
}

}  // namespace spectrack
