// test_util.h: helpers shared by the kernel and image tests: temporary folders, synthetic VDB
// files written with OpenVDB, scene JSON around them, and statistics (mean and standard error).
#pragma once
#include <gtest/gtest.h>
#include <openvdb/openvdb.h>

#include <algorithm>
#include <cstdlib>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "color/spectrum.h"
#include "device/probe.h"
#include "integrator/renderer.h"
#include "scene/scene.h"

namespace st_test {

// The folders temp_dir made during the running test: removed when it ends without a failure (a
// failed test's files stay for a look). Without it every test run leaves ~130 folders in /tmp.
class RemoveDirsOnPass : public testing::EmptyTestEventListener {
 public:
  static std::vector<std::string>& dirs() {
    static std::vector<std::string> d;
    return d;
  }
  void OnTestEnd(const testing::TestInfo& info) override {
    if (info.result() && !info.result()->Failed())
      for (const std::string& d : dirs()) {
        std::error_code ec;
        std::filesystem::remove_all(d, ec);
      }
    dirs().clear();
  }
};
inline const bool kRemoveDirsRegistered = [] {
  testing::UnitTest::GetInstance()->listeners().Append(new RemoveDirsOnPass);
  return true;
}();

inline std::string temp_dir(const std::string& name) {
  auto d = std::filesystem::temp_directory_path() / ("spectrack_test_" + std::to_string(::getpid()) + "_" + name);
  std::filesystem::create_directories(d);
  // only folders made inside a test are the test's (a suite's shared set-up keeps its own)
  if (testing::UnitTest::GetInstance()->current_test_info()) RemoveDirsOnPass::dirs().push_back(d.string());
  return d.string();
}

// Writes float fog grids over the inclusive index box [lo, hi] into one file, with value f(i,j,k)
// (zeros are left inactive), the given voxel size and an origin translation.
inline void write_vdb_grids(const std::string& path, openvdb::Coord lo, openvdb::Coord hi,
                            const std::vector<std::pair<std::string, std::function<float(int, int, int)>>>& grids,
                            double voxel = 1.0, openvdb::Vec3d translate = openvdb::Vec3d(0.0)) {
  openvdb::initialize();
  openvdb::GridPtrVec out;
  for (auto& [name, f] : grids) {
    auto grid = openvdb::FloatGrid::create(0.0f);
    grid->setName(name);
    grid->setGridClass(openvdb::GRID_FOG_VOLUME);
    auto xf = openvdb::math::Transform::createLinearTransform(voxel);
    xf->postTranslate(translate);
    grid->setTransform(xf);
    auto acc = grid->getAccessor();
    for (int k = lo.z(); k <= hi.z(); ++k)
      for (int j = lo.y(); j <= hi.y(); ++j)
        for (int i = lo.x(); i <= hi.x(); ++i) {
          float v = f(i, j, k);
          if (v != 0.0f) acc.setValue(openvdb::Coord(i, j, k), v);
        }
    out.push_back(grid);
  }
  openvdb::io::File file(path);
  file.write(out);
  file.close();
}

// One grid.
inline void write_vdb(const std::string& path, const std::string& name, openvdb::Coord lo, openvdb::Coord hi,
                      const std::function<float(int, int, int)>& f, double voxel = 1.0,
                      openvdb::Vec3d translate = openvdb::Vec3d(0.0)) {
  write_vdb_grids(path, lo, hi, {{name, f}}, voxel, translate);
}

// A chromatic-friendly heterogeneous test volume: smooth lumps and holes inside a ball of
// radius 1 (32^3 voxels of 1/16).
inline void write_lumpy(const std::string& path) {
  write_vdb(path, "density", openvdb::Coord(-16, -16, -16), openvdb::Coord(15, 15, 15),
            [](int i, int j, int k) {
              double r = std::sqrt(double(i * i + j * j + k * k)) / 16.0;
              if (r > 1.0) return 0.0f;
              double v = (1.0 - r) * (0.6 + 0.4 * std::sin(0.5 * i) * std::cos(0.4 * j) * std::sin(0.3 * k + 1.0));
              return float(std::max(0.0, v));
            },
            1.0 / 16.0);
}

inline void write_text(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

// Sets an environment variable for the scope of one test.
struct ScopedEnv {
  std::string name;
  ScopedEnv(const char* n, const char* v) : name(n) { ::setenv(n, v, 1); }
  ~ScopedEnv() { ::unsetenv(name.c_str()); }
};

inline spectrack::SceneDesc scene_from_json(const nlohmann::json& j, const std::string& dir) {
  return spectrack::parse_scene(j.dump(), dir + "/scene.json", dir);
}

struct Stats {
  double mean = 0, se = 0;
};
// Mean and standard error of independent values.
inline Stats mean_se(const std::vector<double>& v) {
  Stats s;
  if (v.empty()) return s;
  double m = 0;
  for (double x : v) m += x;
  m /= double(v.size());
  double var = 0;
  for (double x : v) var += (x - m) * (x - m);
  var /= double(std::max<size_t>(1, v.size() - 1));
  s.mean = m;
  s.se = std::sqrt(var / double(v.size()));
  return s;
}

// Channel c of every pixel of an image (each pixel mean is one independent estimate).
inline std::vector<double> channel(const spectrack::RenderResult& r, int c) {
  std::vector<double> v(size_t(r.width) * r.height);
  for (size_t i = 0; i < v.size(); ++i) v[i] = r.rgb[i * 3 + c];
  return v;
}

// Largest |mean(a - scale_b * b)| / SE over channels and regions (whole image and 4 quadrants):
// under "same expectation" the per-pixel differences are independent zero-mean noise.
inline double max_z(const spectrack::RenderResult& a, const spectrack::RenderResult& b, double scale_b = 1.0) {
  double worst = 0;
  for (int region = -1; region < 4; ++region)
    for (int c = 0; c < 3; ++c) {
      std::vector<double> d;
      for (int y = 0; y < a.height; ++y)
        for (int x = 0; x < a.width; ++x) {
          int q = (y * 2 / a.height) * 2 + (x * 2 / a.width);
          if (region >= 0 && q != region) continue;
          size_t i = (size_t(y) * a.width + x) * 3 + c;
          d.push_back(a.rgb[i] - scale_b * b.rgb[i]);
        }
      Stats s = mean_se(d);
      double z = std::abs(s.mean) / std::max(s.se, 1e-12);
      worst = std::max(worst, z);
    }
  return worst;
}

// Runs fn and returns the spectrack::Error message; fails the test on success or other throws.
template <class Fn>
std::string error_of(Fn fn) {
  try {
    fn();
  } catch (const spectrack::Error& e) {
    return e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << "expected spectrack::Error, got another exception: " << e.what();
    return "";
  }
  ADD_FAILURE() << "expected spectrack::Error, got success";
  return "";
}

inline spectrack::RenderOptions quiet_options(int spp = -1) {
  spectrack::RenderOptions o;
  o.quiet = true;
  if (spp > 0) o.spp = spp;
  return o;
}

// Spectral mode's film (src/color/spectrum.h): the linear sRGB of a radiance spectrum L(lambda),
// summed over the observer's 1 nm grid with the film's weights; what a spectral render estimates.
inline spectrack::Rgb film_of(const std::function<double(double)>& L) {
  const std::vector<spectrack::Rgb>& F = spectrack::film_rgb_weights();
  spectrack::Rgb out{0, 0, 0};
  for (size_t i = 0; i < F.size(); ++i) {
    const double l = L(spectrack::kSpectrumLambdaMin + double(i));
    for (int c = 0; c < 3; ++c) out[c] += l * F[i][c];
  }
  return out;
}

}  // namespace st_test
