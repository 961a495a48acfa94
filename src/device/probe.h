// probe.h: the kernels' own device functions run in isolation, for tests and benchmarks.
//
// Design: a Probe works on a Renderer's uploaded scene (device/device_scene.h) but builds its own
// OpenCL program, the renderer's source plus kernels/probe.cl, so no production program carries
// the probe kernels; this file is compiled into the spectrack_probe library, which only the test
// and benchmark programs link. Every probe is one named, profiled launch with its own random
// stream per item (pixel = item index, stream = 7).
#pragma once
#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "integrator/renderer.h"

namespace cl {
class Buffer;
}

namespace spectrack {

class KernelLauncher;

class Probe {
 public:
  explicit Probe(Renderer& renderer);
  ~Probe();
  Probe(const Probe&) = delete;
  Probe& operator=(const Probe&) = delete;

  // Density of a medium at world points, each at its time in `times` (seconds; a moving medium's
  // lookup, kernels/medium.h; none: time 0).
  std::vector<float> density(int medium, const std::vector<std::array<float, 3>>& world_points,
                             const std::vector<float>& times = {});
  // (dmax, dmin) of the majorant cell holding each point ((-1, -1) outside the medium's box).
  std::vector<std::array<float, 2>> majorant(int medium, const std::vector<std::array<float, 3>>& world_points);
  // The majorant segments of medium `medium`'s DDA along the world ray (o, d) from t = 0, at most
  // max_segments: (t0, t1, dmax, dmin) each, in order (zero-length ones at edges and corners too).
  std::vector<std::array<float, 4>> segments(int medium, std::array<float, 3> o, std::array<float, 3> d,
                                             int max_segments = 4096);
  // Per item: (t of first real collision or +inf, event, lookups, dda steps); channel -1 = rgb.
  std::vector<std::array<float, 4>> track(std::array<float, 3> o, std::array<float, 3> d, int channel, int n,
                                          std::vector<std::array<float, 4>>* beta = nullptr);
  // Infinite-medium albedo walks from o: per item (sum of scattering weights xyz, max weight) and
  // (absorption score with Le = 1 xyz, escaped flag). channel -1 = rgb.
  void albedo(std::array<float, 3> o, int channel, int n, std::vector<std::array<float, 4>>* scatter,
              std::vector<std::array<float, 4>>* absorb);
  // Spectral mode's device functions (kernels/spectrum.h) on items (r, g, b, u): the colour's
  // table coefficients (c0, c1, c2, scale), the four wavelengths of u and their pdfs, the colour's
  // spectrum at them, and the film's linear sRGB of that spectrum taken as a radiance.
  struct SpectrumItem {
    std::array<float, 4> coeffs, lambda, pdf, value;
    std::array<float, 3> film_rgb;
  };
  std::vector<SpectrumItem> spectrum(const std::vector<std::array<float, 4>>& rgb_u);
  // Phase sampling around +z: per item (cos theta, pdf, phase value, |wi| - 1).
  std::vector<std::array<float, 4>> phase(int type, float g, int n);
  // The same for any phase (type, g, b) (kernels/phase.h): per item the four lanes above, then
  // (the phase value the sampler reports, the draws of the path's stream it took in all, 0, 0).
  std::vector<std::array<float, 8>> phase(int type, float g, std::array<float, 4> b, int n);
  // The phase value at each cosine (twice: the kernel writes float2).
  std::vector<std::array<float, 2>> phase_eval(int type, float g, std::array<float, 4> b,
                                               const std::vector<float>& cos_theta);
  // Transmittance from o along d to the end of every medium, per item and channel, by the
  // renderer's estimator (ratio tracking or ray marching); stats: per item (density lookups, DDA steps, 0, 0).
  std::vector<std::array<float, 4>> transmittance(std::array<float, 3> o, std::array<float, 3> d, int n,
                                                  std::vector<std::array<float, 4>>* stats = nullptr);
  // Raw uniforms of the renderer's generator (kernels/rng.h): n streams, stream i being
  // (pixel, sample, channel, stream) = base with component `axis` (0..3) increased by i; draws
  // first_draw .. first_draw + n_draws - 1 of each, out[i * n_draws + k]. resume_every > 0
  // rebuilds the generator from its draw index every resume_every draws (a re-queued path).
  std::vector<float> uniforms(std::array<uint32_t, 4> base, int axis, uint32_t first_draw, uint32_t n_draws, int n,
                              uint32_t resume_every = 0);
  // The bare Philox4x32-10 block function of the kernels on (counter, key) pairs.
  std::vector<std::array<uint32_t, 4>> philox(const std::vector<std::pair<std::array<uint32_t, 4>, std::array<uint32_t, 2>>>& in);

 private:
  DeviceScene& ds() { return renderer_.device_scene(); }
  template <typename T>
  std::vector<T> per_point(const char* kernel, const cl::Buffer& data, int medium,
                           const std::vector<std::array<float, 3>>& world_points,
                           const std::vector<float>& times);
  Renderer& renderer_;
  std::unique_ptr<KernelLauncher> launcher_;
};

}  // namespace spectrack
