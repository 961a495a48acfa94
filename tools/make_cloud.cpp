// make_cloud: writes the procedural cumulus cloud used by the default scene.
//
//   make_cloud OUT.vdb [--res N] [--style cumulus|dense|fire] [--color]
//
// Design: a handful of overlapping spheres (a flat-bottomed cumulus heap) give a smooth
// "depth inside the cloud" field; fractal value noise displaces that field, so the surface
// billows, and modulates the interior. Density = smoothstep of the displaced depth, so the edges
// are soft and the core approaches 1. Everything derives from integer hashing with a fixed
// seed (no std random distributions, whose output differs between library versions), so the
// same --res gives the same file. The cloud spans about [-1,1]^3 in world units: the grid has
// N voxels across, voxel size 2/N, and voxel centres at -1 + (i + 0.5) * 2/N. The result is a
// float fog-volume grid named "density" with background 0, written with OpenVDB's default
// (Blosc) compression.
// --style dense (the benchmark's subsurface-like medium, bench/scenes/dense_subsurface.json) keeps
// the heap's silhouette but makes it a solid: a sharp edge (a few voxels) and an interior that
// varies only mildly (0.8 to 1.0 of the peak), so the per-cell minorant stays close to the
// majorant, which is the regime decomposition tracking is built for.
// --style fire (data/scenes/fire.json): a rising, turbulent plume, its density with a second float
// grid "temperature" in kelvin on the same voxels: ~1900 K in the core at the base, cooling with
// height and towards the plume's edge to ~500 K in the smoke at the top (a blackbody emission's
// grid: docs/scene-format.md "Blackbody emission").
// --color adds a vec3s grid "Cd" on the density's active voxels and transform: a single-scattering
// albedo from a warm, absorbing base (0.9, 0.6, 0.35) to a near-white top (0.97, 0.95, 0.92),
// blended by height and noise (docs/examples/colored_smoke.json; a medium's "color" field).
#include <openvdb/openvdb.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <string>
#include <thread>
#include <vector>

#include "kernels/hash.h"  // st_hash32

namespace {

constexpr uint32_t kSeed = 0x5eed1234u;

uint32_t hash3(int x, int y, int z, uint32_t seed) {
  return st_hash32(seed ^ (uint32_t(x) * 0x8da6b343u) ^ (uint32_t(y) * 0xd8163841u) ^ (uint32_t(z) * 0xcb1ab31fu));
}

double lattice(int x, int y, int z, uint32_t seed) { return hash3(x, y, z, seed) * (1.0 / 4294967296.0); }

double fade(double t) { return t * t * t * (t * (t * 6 - 15) + 10); }

// Value noise in [0,1): quintic interpolation of hashed lattice values.
double value_noise(double x, double y, double z, uint32_t seed) {
  const double fx = std::floor(x), fy = std::floor(y), fz = std::floor(z);
  const int ix = int(fx), iy = int(fy), iz = int(fz);
  const double u = fade(x - fx), v = fade(y - fy), w = fade(z - fz);
  double c[2][2];
  for (int k = 0; k < 2; ++k)
    for (int j = 0; j < 2; ++j) {
      const double a = lattice(ix, iy + j, iz + k, seed), b = lattice(ix + 1, iy + j, iz + k, seed);
      c[k][j] = a + u * (b - a);
    }
  const double c0 = c[0][0] + v * (c[0][1] - c[0][0]);
  const double c1 = c[1][0] + v * (c[1][1] - c[1][0]);
  return c0 + w * (c1 - c0);
}

// Fractal sum of octaves, normalised to [0,1).
double fbm(double x, double y, double z, int octaves, uint32_t seed) {
  double sum = 0, amp = 0.5, norm = 0;
  for (int o = 0; o < octaves; ++o) {
    sum += amp * value_noise(x, y, z, seed + uint32_t(o) * 1013u);
    norm += amp;
    amp *= 0.5;
    x = x * 2.03 + 17.1;
    y = y * 2.03 - 9.3;
    z = z * 2.03 + 3.7;
  }
  return sum / norm;
}

double smoothstep(double a, double b, double x) {
  const double t = std::clamp((x - a) / (b - a), 0.0, 1.0);
  return t * t * (3 - 2 * t);
}

struct Sphere {
  double x, y, z, r;
};

// The heap: a broad base, a central tower and side lobes, all inside |p| < ~0.8.
const Sphere kSpheres[] = {
    {0.00, -0.15, 0.00, 0.50}, {-0.40, -0.25, 0.10, 0.36}, {0.42, -0.22, -0.08, 0.38},
    {0.08, 0.22, 0.04, 0.40},  {-0.18, 0.12, -0.30, 0.32}, {0.22, -0.28, 0.36, 0.30},
    {-0.05, 0.48, -0.05, 0.26},
};

// Depth inside the soft union of spheres, in units of each radius (1 at a centre), at a point of
// the heap's frame.
double heap_depth(double x, double y, double z) {
  double depth = -1e9;
  for (const Sphere& s : kSpheres) {
    const double d = std::sqrt((x - s.x) * (x - s.x) + (y - s.y) * (y - s.y) + (z - s.z) * (z - s.z));
    depth = std::max(depth, 1.0 - d / s.r);
  }
  return depth;
}

// Density at world point p in [-1,1]^3.
double cloud_density(double x, double y, double z) {
  // The heap is modelled in a slightly smaller frame so that it fills about [-0.9, 0.9]^3.
  x /= 1.08, y /= 1.08, z /= 1.08;
  const double depth = heap_depth(x, y, z);
  if (depth < -0.6) return 0.0;
  const double billow = fbm(x * 3.1, y * 3.1, z * 3.1, 5, kSeed) - 0.5;
  // Folded noise gives rounded cauliflower lumps rather than a smooth wobble.
  const double lumps = 0.5 - std::abs(2.0 * fbm(x * 6.3 + 5.2, y * 6.3, z * 6.3 - 1.3, 3, kSeed + 77u) - 1.0);
  const double shaped = depth + 0.75 * billow + 0.3 * lumps;
  // Flat, slightly ragged base.
  const double base = smoothstep(-0.50, -0.36, y + 0.05 * billow);
  const double body = smoothstep(0.0, 0.55, shaped);
  const double texture = 0.75 + 0.5 * (fbm(x * 6.0, y * 6.0, z * 6.0, 4, kSeed + 991u) - 0.5);
  return std::clamp(body * base * texture, 0.0, 1.0);
}

// The dense style: the same heap, a sharp edge and a mildly varying interior.
double dense_density(double x, double y, double z) {
  x /= 1.08, y /= 1.08, z /= 1.08;
  const double depth = heap_depth(x, y, z);
  if (depth < -0.3) return 0.0;
  const double billow = fbm(x * 3.1, y * 3.1, z * 3.1, 4, kSeed) - 0.5;
  const double body = smoothstep(0.0, 0.06, depth + 0.25 * billow);
  const double interior = 0.8 + 0.2 * fbm(x * 4.0 + 2.1, y * 4.0, z * 4.0 - 0.7, 3, kSeed + 4242u);
  return std::clamp(body * interior, 0.0, 1.0);
}

// The fire style: density and temperature (K) at world point p in [-1,1]^3. The plume rises along
// +y from y = -0.85, widening and slowed by noise; heat is highest on the axis near the base.
double fire_density(double x, double y, double z, double* temperature) {
  *temperature = 0;
  const double h = (y + 0.85) / 1.7;  // 0 at the base, 1 at the top
  if (h < -0.05 || h > 1.05) return 0.0;
  const double swirl = fbm(x * 2.5 + 3.3, y * 2.5 - 4.0 * h, z * 2.5 + 1.1, 4, kSeed + 313u) - 0.5;
  const double cx = 0.18 * swirl * h, cz = 0.18 * (fbm(x * 2.5, y * 2.5, z * 2.5, 3, kSeed + 929u) - 0.5) * h;
  const double radius = 0.22 + 0.4 * h;
  const double d = std::sqrt((x - cx) * (x - cx) + (z - cz) * (z - cz)) / radius;
  const double billow = fbm(x * 5.0, y * 5.0 - 3.0 * h, z * 5.0, 4, kSeed + 55u) - 0.5;
  const double shape = 1.0 - d + 0.6 * billow;
  if (shape <= 0) return 0.0;
  const double ends = smoothstep(-0.05, 0.06, h) * (1.0 - smoothstep(0.8, 1.05, h + 0.2 * billow));
  const double density = std::clamp(smoothstep(0.0, 0.35, shape) * ends * (0.6 + 0.8 * (fbm(x * 8.0, y * 8.0, z * 8.0, 3, kSeed + 7u))), 0.0, 1.0);
  const double core = smoothstep(0.05, 0.75, shape) * std::exp(-1.4 * h);
  const double flicker = 0.75 + 0.5 * fbm(x * 6.0 + 9.0, y * 6.0 - 5.0 * h, z * 6.0, 3, kSeed + 1234u);
  *temperature = 500.0 + 1400.0 * std::clamp(core * flicker, 0.0, 1.0);
  return density;
}

int usage(const char* argv0) {
  std::cerr << "usage: " << argv0 << " OUT.vdb [--res N] [--style cumulus|dense|fire] [--color]   (N voxels across, 16..512, default 96)\n";
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  std::string out;
  int res = 96;
  bool dense_style = false, fire_style = false, color = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--res" && i + 1 < argc) {
      char* end = nullptr;
      const long v = std::strtol(argv[++i], &end, 10);
      if (*end != '\0' || v < 16 || v > 512) return usage(argv[0]);
      res = int(v);
    } else if (a == "--style" && i + 1 < argc) {
      const std::string v = argv[++i];
      if (v != "cumulus" && v != "dense" && v != "fire") return usage(argv[0]);
      dense_style = v == "dense";
      fire_style = v == "fire";
    } else if (a == "--color") {
      color = true;
    } else if (a == "-h" || a == "--help") {
      return usage(argv[0]);
    } else if (out.empty() && !a.empty() && a[0] != '-') {
      out = a;
    } else {
      return usage(argv[0]);
    }
  }
  if (out.empty()) return usage(argv[0]);

  // Dense evaluation, one z-slice at a time across threads; then a serial copy into the tree.
  const double vs = 2.0 / res;
  std::vector<float> dense(size_t(res) * res * res, 0.0f);
  std::vector<float> temperature(fire_style ? dense.size() : 0, 0.0f);
  std::atomic<int> next{0};
  auto worker = [&] {
    for (int k; (k = next.fetch_add(1)) < res;) {
      const double z = -1.0 + (k + 0.5) * vs;
      for (int j = 0; j < res; ++j)
        for (int i = 0; i < res; ++i) {
          const double x = -1.0 + (i + 0.5) * vs, y = -1.0 + (j + 0.5) * vs;
          const size_t at = (size_t(k) * res + j) * res + i;
          if (fire_style) {
            double T = 0;
            dense[at] = float(fire_density(x, y, z, &T));
            temperature[at] = float(T);
          } else {
            dense[at] = float(dense_style ? dense_density(x, y, z) : cloud_density(x, y, z));
          }
        }
    }
  };
  std::vector<std::thread> threads;
  const unsigned n = std::max(1u, std::min(16u, std::thread::hardware_concurrency()));
  for (unsigned t = 0; t < n; ++t) threads.emplace_back(worker);
  for (auto& t : threads) t.join();

  try {
    openvdb::initialize();
    openvdb::FloatGrid::Ptr grid = openvdb::FloatGrid::create(0.0f);
    auto acc = grid->getAccessor();
    for (int k = 0; k < res; ++k)
      for (int j = 0; j < res; ++j)
        for (int i = 0; i < res; ++i) {
          const float v = dense[(size_t(k) * res + j) * res + i];
          if (v > 1e-3f) acc.setValue(openvdb::Coord(i, j, k), v);
        }
    grid->setName("density");
    grid->setGridClass(openvdb::GRID_FOG_VOLUME);
    auto xf = openvdb::math::Transform::createLinearTransform(vs);
    xf->postTranslate(openvdb::Vec3d(-1.0 + 0.5 * vs));
    grid->setTransform(xf);
    grid->insertMeta("creator", openvdb::StringMetadata("spectrack make_cloud"));
    grid->insertMeta("make_cloud_res", openvdb::Int32Metadata(res));
    grid->insertMeta("make_cloud_style", openvdb::StringMetadata(fire_style ? "fire" : dense_style ? "dense" : "cumulus"));

    openvdb::GridPtrVec grids{grid};
    if (fire_style) {
      openvdb::FloatGrid::Ptr tg = openvdb::FloatGrid::create(0.0f);
      tg->setName("temperature");
      tg->setGridClass(openvdb::GRID_FOG_VOLUME);
      tg->setTransform(xf->copy());
      auto tacc = tg->getAccessor();
      for (auto it = grid->cbeginValueOn(); it; ++it) {
        const openvdb::Coord q = it.getCoord();
        tacc.setValue(q, temperature[(size_t(q.z()) * res + q.y()) * res + q.x()]);
      }
      grids.push_back(tg);
    }
    if (color) {
      openvdb::Vec3SGrid::Ptr cd = openvdb::Vec3SGrid::create(openvdb::Vec3s(0.0f));
      cd->setName("Cd");
      cd->setTransform(xf->copy());
      auto cacc = cd->getAccessor();
      for (auto it = grid->cbeginValueOn(); it; ++it) {
        const openvdb::Coord q = it.getCoord();
        const double y = -1.0 + (q.y() + 0.5) * vs;
        const double t = std::clamp(0.5 + 0.6 * y + 0.25 * (fbm(q.x() * vs * 3.0, y * 3.0, q.z() * vs * 3.0, 3, 77u) - 0.5), 0.0, 1.0);
        cacc.setValue(q, openvdb::Vec3s(float(0.9 + 0.07 * t), float(0.6 + 0.35 * t), float(0.35 + 0.57 * t)));
      }
      grids.push_back(cd);
    }
    openvdb::io::File file(out);
    file.write(grids);
    file.close();

    const openvdb::CoordBBox box = grid->evalActiveVoxelBoundingBox();
    const openvdb::BBoxd wbox = grid->transform().indexToWorld(box);
    float vmin = 1, vmax = 0;
    for (auto it = grid->cbeginValueOn(); it; ++it) vmin = std::min(vmin, *it), vmax = std::max(vmax, *it);
    std::cout << out << ": " << grid->activeVoxelCount() << " active voxels, index bbox " << box.min() << " -> "
              << box.max() << ", world bbox " << wbox.min() << " -> " << wbox.max() << ", voxel size " << vs
              << ", density " << vmin << " .. " << vmax << ", " << std::filesystem::file_size(out) << " bytes\n";
  } catch (const std::exception& e) {
    std::cerr << "make_cloud: " << out << ": " << e.what() << "\n";
    return 1;
  }
  return 0;
}
