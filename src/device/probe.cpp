// probe.cpp: see probe.h.
#include "device/probe.h"

#include <fmt/format.h>

#include <algorithm>
#include <functional>

#include "color/spectrum.h"
#include "device/device_scene.h"

namespace spectrack {

Probe::Probe(Renderer& renderer) : renderer_(renderer) {
  DeviceScene& d = renderer_.device_scene();
  ProgramBuild pb = build_program(d.ctx, d.dev, assemble_kernel_source(d.defines, {"probe.cl"}), "-cl-std=CL1.2", true);
  launcher_ = std::make_unique<KernelLauncher>(d.queue, pb.program);
}
Probe::~Probe() = default;

namespace {

// One named launch of n items; `args` binds the kernel's arguments and the output buffer.
template <typename T>
std::vector<T> run_probe(DeviceScene& d, KernelLauncher& launcher, const std::string& name, size_t n,
                         const std::function<void(cl::Kernel&, cl::Buffer&)>& args) {
  std::vector<T> out(n);
  if (n == 0) return out;
  cl::Buffer b_out = d.buffer(CL_MEM_WRITE_ONLY, n * sizeof(T), nullptr, "probe output");
  cl::Kernel& k = launcher.kernel(name);
  args(k, b_out);
  launcher.launch(name, n);
  ST_CL_CHECK(d.queue.enqueueReadBuffer(b_out, CL_TRUE, 0, n * sizeof(T), out.data()), ("read " + name).c_str());
  launcher.collect_profiling();
  return out;
}

// w: the point's time (seconds; 0 without times)
std::vector<st_float4> to_points(const std::vector<std::array<float, 3>>& pts, const std::vector<float>& times) {
  std::vector<st_float4> v(pts.size());
  for (size_t i = 0; i < pts.size(); ++i) v[i] = st_float4{pts[i][0], pts[i][1], pts[i][2], i < times.size() ? times[i] : 0.0f};
  return v;
}

}  // namespace



// A probe over world points of one medium: kernel(scene, data, points, out, medium, n).
template <typename T>
std::vector<T> Probe::per_point(const char* kernel, const cl::Buffer& data, int medium,
                                const std::vector<std::array<float, 3>>& world_points, const std::vector<float>& times) {
  if (medium < 0 || medium >= ds().packed.st.n_media) throw Error(fmt::format("{}: no such medium {}", kernel, medium));
  auto pts = to_points(world_points, times);
  cl::Buffer b_pts = ds().buffer(CL_MEM_READ_ONLY, std::max<size_t>(1, pts.size()) * 16, pts.empty() ? nullptr : pts.data(), "probe points");
  return run_probe<T>(ds(), *launcher_, kernel, pts.size(), [&](cl::Kernel& k, cl::Buffer& out) {
    k.setArg(0, ds().b_scene);
    k.setArg(1, data);
    k.setArg(2, b_pts);
    k.setArg(3, out);
    k.setArg(4, cl_int(medium));
    k.setArg(5, cl_uint(pts.size()));
  });
}

std::vector<float> Probe::density(int medium, const std::vector<std::array<float, 3>>& world_points,
                                  const std::vector<float>& times) {
  return per_point<float>("k_probe_density", ds().b_grids, medium, world_points, times);
}

std::vector<std::array<float, 2>> Probe::majorant(int medium, const std::vector<std::array<float, 3>>& world_points) {
  return per_point<std::array<float, 2>>("k_probe_majorant", ds().b_maj, medium, world_points, {});
}

std::vector<std::array<float, 4>> Probe::segments(int medium, std::array<float, 3> o, std::array<float, 3> d,
                                                  int max_segments) {
  if (medium < 0 || medium >= ds().packed.st.n_media) throw Error(fmt::format("k_probe_segments: no such medium {}", medium));
  auto out = run_probe<std::array<float, 4>>(ds(), *launcher_, "k_probe_segments", size_t(max_segments),
                                             [&](cl::Kernel& k, cl::Buffer& out) {
                                               k.setArg(0, ds().b_scene);
                                               k.setArg(1, ds().b_maj);
                                               k.setArg(2, cl_float4{{o[0], o[1], o[2], 0}});
                                               k.setArg(3, cl_float4{{d[0], d[1], d[2], 0}});
                                               k.setArg(4, cl_int(medium));
                                               k.setArg(5, out);
                                               k.setArg(6, cl_uint(max_segments));
                                             });
  while (!out.empty() && out.back()[0] == -1.0f && out.back()[1] == -1.0f) out.pop_back();
  return out;
}

std::vector<std::array<float, 4>> Probe::track(std::array<float, 3> o, std::array<float, 3> d, int channel, int n,
                                                        std::vector<std::array<float, 4>>* beta) {
  cl::Buffer b_beta = ds().buffer(CL_MEM_READ_WRITE, size_t(std::max(1, n)) * 16, nullptr, "probe beta");
  auto out = run_probe<std::array<float, 4>>(ds(), *launcher_, "k_probe_track", size_t(n), [&](cl::Kernel& k, cl::Buffer& out) {
    k.setArg(0, ds().b_scene);
    k.setArg(1, ds().b_grids);
    k.setArg(2, ds().b_maj);
    k.setArg(3, cl_float4{{o[0], o[1], o[2], 0}});
    k.setArg(4, cl_float4{{d[0], d[1], d[2], 0}});
    k.setArg(5, cl_int(channel));
    k.setArg(6, out);
    k.setArg(7, b_beta);
    k.setArg(8, cl_uint(n));
  });
  if (beta) {
    beta->resize(size_t(n));
    if (n > 0)
      ST_CL_CHECK(ds().queue.enqueueReadBuffer(b_beta, CL_TRUE, 0, size_t(n) * 16, beta->data()), "read probe beta");
  }
  return out;
}

void Probe::albedo(std::array<float, 3> o, int channel, int n, std::vector<std::array<float, 4>>* scatter,
                            std::vector<std::array<float, 4>>* absorb) {
  cl::Buffer b_abs = ds().buffer(CL_MEM_READ_WRITE, size_t(std::max(1, n)) * 16, nullptr, "probe absorption");
  *scatter = run_probe<std::array<float, 4>>(ds(), *launcher_, "k_probe_albedo", size_t(n), [&](cl::Kernel& k, cl::Buffer& out) {
    k.setArg(0, ds().b_scene);
    k.setArg(1, ds().b_grids);
    k.setArg(2, ds().b_maj);
    k.setArg(3, cl_float4{{o[0], o[1], o[2], 0}});
    k.setArg(4, cl_int(channel));
    k.setArg(5, out);
    k.setArg(6, b_abs);
    k.setArg(7, cl_uint(n));
  });
  absorb->resize(size_t(n));
  if (n > 0) ST_CL_CHECK(ds().queue.enqueueReadBuffer(b_abs, CL_TRUE, 0, size_t(n) * 16, absorb->data()), "read probe absorption");
}

std::vector<std::array<float, 8>> Probe::phase(int type, float g, std::array<float, 4> b, int n) {
  return run_probe<std::array<float, 8>>(ds(), *launcher_, "k_probe_phase", size_t(n), [&](cl::Kernel& k, cl::Buffer& out) {
    k.setArg(0, ds().b_scene);
    k.setArg(1, cl_int(type));
    k.setArg(2, cl_float(g));
    k.setArg(3, cl_float4{{b[0], b[1], b[2], b[3]}});
    k.setArg(4, out);
    k.setArg(5, cl_uint(n));
  });
}

std::vector<std::array<float, 4>> Probe::phase(int type, float g, int n) {
  std::vector<std::array<float, 4>> out;
  for (const auto& x : phase(type, g, {0, 0, 0, 0}, n)) out.push_back({x[0], x[1], x[2], x[3]});
  return out;
}

std::vector<std::array<float, 2>> Probe::phase_eval(int type, float g, std::array<float, 4> b,
                                                    const std::vector<float>& cos_theta) {
  const size_t n = cos_theta.size();
  if (n == 0) return {};
  cl::Buffer b_cos = ds().buffer(CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, n * sizeof(float),
                                 cos_theta.data(), "probe cosines");
  return run_probe<std::array<float, 2>>(ds(), *launcher_, "k_probe_phase_eval", n, [&](cl::Kernel& k, cl::Buffer& out) {
    k.setArg(0, ds().b_scene);
    k.setArg(1, cl_int(type));
    k.setArg(2, cl_float(g));
    k.setArg(3, cl_float4{{b[0], b[1], b[2], b[3]}});
    k.setArg(4, b_cos);
    k.setArg(5, out);
    k.setArg(6, cl_uint(n));
  });
}

std::vector<std::array<float, 4>> Probe::transmittance(std::array<float, 3> o, std::array<float, 3> d, int n,
                                                        std::vector<std::array<float, 4>>* stats) {
  cl::Buffer b_stats = ds().buffer(CL_MEM_READ_WRITE, size_t(std::max(1, n)) * 16, nullptr, "probe transmittance stats");
  auto out = run_probe<std::array<float, 4>>(ds(), *launcher_, "k_probe_transmittance", size_t(n), [&](cl::Kernel& k, cl::Buffer& out) {
    k.setArg(0, ds().b_scene);
    k.setArg(1, ds().b_grids);
    k.setArg(2, ds().b_maj);
    k.setArg(3, cl_float4{{o[0], o[1], o[2], 0}});
    k.setArg(4, cl_float4{{d[0], d[1], d[2], 0}});
    k.setArg(5, out);
    k.setArg(6, b_stats);
    k.setArg(7, cl_uint(n));
  });
  if (stats) {
    stats->resize(size_t(n));
    if (n > 0)
      ST_CL_CHECK(ds().queue.enqueueReadBuffer(b_stats, CL_TRUE, 0, size_t(n) * 16, stats->data()),
                  "read probe transmittance stats");
  }
  return out;
}

std::vector<float> Probe::uniforms(std::array<uint32_t, 4> base, int axis, uint32_t first_draw, uint32_t n_draws, int n,
                                  uint32_t resume_every) {
  if (axis < 0 || axis > 3) throw Error(fmt::format("uniforms: axis {} is not 0..3", axis));
  const size_t total = size_t(std::max(0, n)) * n_draws;
  std::vector<float> out(total);
  if (total == 0) return out;
  cl::Buffer b_out = ds().buffer(CL_MEM_WRITE_ONLY, total * sizeof(float), nullptr, "probe uniforms");
  cl::Kernel& k = launcher_->kernel("k_probe_uniforms");
  k.setArg(0, ds().b_scene);
  k.setArg(1, cl_uint4{{base[0], base[1], base[2], base[3]}});
  k.setArg(2, cl_int(axis));
  k.setArg(3, cl_uint(first_draw));
  k.setArg(4, cl_uint(n_draws));
  k.setArg(5, cl_uint(resume_every));
  k.setArg(6, b_out);
  k.setArg(7, cl_uint(n));
  launcher_->launch("k_probe_uniforms", size_t(n));
  ST_CL_CHECK(ds().queue.enqueueReadBuffer(b_out, CL_TRUE, 0, total * sizeof(float), out.data()), "read probe uniforms");
  launcher_->collect_profiling();
  return out;
}

std::vector<std::array<uint32_t, 4>> Probe::philox(
    const std::vector<std::pair<std::array<uint32_t, 4>, std::array<uint32_t, 2>>>& in) {
  std::vector<cl_uint4> io(2 * std::max<size_t>(1, in.size()));
  for (size_t i = 0; i < in.size(); ++i) {
    io[2 * i] = cl_uint4{{in[i].first[0], in[i].first[1], in[i].first[2], in[i].first[3]}};
    io[2 * i + 1] = cl_uint4{{in[i].second[0], in[i].second[1], 0, 0}};
  }
  std::vector<std::array<uint32_t, 4>> out(in.size());
  if (in.empty()) return out;
  cl::Buffer b_io = ds().buffer(CL_MEM_READ_WRITE, io.size() * sizeof(cl_uint4), io.data(), "probe philox");
  cl::Kernel& k = launcher_->kernel("k_probe_philox");
  k.setArg(0, b_io);
  k.setArg(1, cl_uint(in.size()));
  launcher_->launch("k_probe_philox", in.size());
  ST_CL_CHECK(ds().queue.enqueueReadBuffer(b_io, CL_TRUE, 0, io.size() * sizeof(cl_uint4), io.data()), "read probe philox");
  launcher_->collect_profiling();
  for (size_t i = 0; i < in.size(); ++i) out[i] = {io[2 * i].s[0], io[2 * i].s[1], io[2 * i].s[2], io[2 * i].s[3]};
  return out;
}

std::vector<Probe::SpectrumItem> Probe::spectrum(const std::vector<std::array<float, 4>>& rgb_u) {
  std::vector<SpectrumItem> out(rgb_u.size());
  if (rgb_u.empty()) return out;
  const Rgb2SpecTable& t = rgb2spec_srgb();
  std::vector<float> table(t.z.begin(), t.z.end());
  table.insert(table.end(), t.coeffs.begin(), t.coeffs.end());
  cl::Buffer b_table = ds().buffer(CL_MEM_READ_ONLY, table.size() * 4, table.data(), "probe rgb2spec table");
  cl::Buffer b_in = ds().buffer(CL_MEM_READ_ONLY, rgb_u.size() * 16, rgb_u.data(), "probe spectrum input");
  cl::Buffer b_out = ds().buffer(CL_MEM_WRITE_ONLY, rgb_u.size() * 64, nullptr, "probe spectrum output");
  cl::Buffer b_spec = ds().buffer(CL_MEM_WRITE_ONLY, rgb_u.size() * 16, nullptr, "probe spectrum values");
  cl::Kernel& k = launcher_->kernel("k_probe_spectrum");
  k.setArg(0, b_table);
  k.setArg(1, cl_int(t.res));
  k.setArg(2, b_in);
  k.setArg(3, b_out);
  k.setArg(4, b_spec);
  k.setArg(5, cl_uint(rgb_u.size()));
  launcher_->launch("k_probe_spectrum", rgb_u.size());
  std::vector<std::array<float, 16>> o(rgb_u.size());
  std::vector<std::array<float, 4>> sp(rgb_u.size());
  ST_CL_CHECK(ds().queue.enqueueReadBuffer(b_out, CL_TRUE, 0, o.size() * 64, o.data()), "read probe spectrum");
  ST_CL_CHECK(ds().queue.enqueueReadBuffer(b_spec, CL_TRUE, 0, sp.size() * 16, sp.data()), "read probe spectrum values");
  launcher_->collect_profiling();
  for (size_t i = 0; i < o.size(); ++i) {
    for (int k2 = 0; k2 < 4; ++k2) {
      out[i].coeffs[k2] = o[i][k2];
      out[i].lambda[k2] = o[i][4 + k2];
      out[i].pdf[k2] = o[i][8 + k2];
      out[i].value[k2] = sp[i][k2];
    }
    for (int k2 = 0; k2 < 3; ++k2) out[i].film_rgb[k2] = o[i][12 + k2];
  }
  return out;
}

}  // namespace spectrack
