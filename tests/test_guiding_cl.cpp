// test_guiding_cl.cpp: kernels/guiding.h compiled as OpenCL C on the default device (PoCL here)
// in a small program of its own (types.h, features.h, sampling.h, phase.h, guiding.h and a probe
// kernel):
//   - the device's lobe and mixture pdfs equal the host's within float rounding (kappa 0 to 1e4);
//   - the device's vMF samples and guided scatter directions (one-sample mixture with
//     Henyey-Greenstein) equal the host's for the same uniforms, and its mixture pdf and phase
//     value are those the host computes at the device's direction;
//   - the device's guided estimator, with a guide pointing away from the light, estimates the
//     integral of f_phase g within 4 standard errors; twin: the pdf 3% off is detected;
//   - the renderer's program contains guiding.h (its kernels use it only with ST_FEATURE_GUIDING).
#include "device/opencl.h"
#include "guiding_util.h"

using namespace guiding_test;

namespace {

const char* kProbe = R"CL(
__kernel void k_guiding_probe(__global const st_vmf_mixture* mix, __global const float4* dirs,
                              __global const float4* us, float alpha, float g, float4 wo, float4 mu,
                              uint n, __global float* out_pdf, __global float* out_lobe,
                              __global float4* out_vmf, __global float4* out_guided, __global float* out_f) {
  uint i = get_global_id(0);
  if (i >= n) return;
  float4 d = dirs[i]; /* xyz: a direction; w: a kappa for the lobe around mu */
  float4 u = us[i];
  out_pdf[i] = vmf_mixture_pdf(mix, d.xyz);
  out_lobe[i] = vmf_eval(mu.xyz, d.w, d.xyz);
  out_vmf[i] = (float4)(vmf_sample(mu.xyz, d.w, u.y, u.z), 0.0f);
  float pdf, f;
  float3 wi = guided_phase_sample(mix, alpha, ST_PHASE_HG, g, (float4)(0.0f), wo.xyz, u.x, u.y, u.z, 0, &pdf, &f, 0.0f);
  out_guided[i] = (float4)(wi, pdf);
  out_f[i] = f;
}
)CL";

std::string probe_source() {
  return "#pragma OPENCL FP_CONTRACT OFF\n" + spectrack::kernel_files_source({"guiding.h"}) + kProbe;
}

// Henyey-Greenstein sampled in double in the frame phase.h uses (Duff et al.'s, as vmf_frame), so
// that the device's phase branch can be compared direction for direction.
st_vec3 hg_sample_in_device_frame(double g, st_vec3 wo, double u1, double u2) {
  st_vec3 t, b;
  vmf_frame(wo, &t, &b);
  double s = (1 - g * g) / (1 - g + 2 * g * u1), c = (1 + g * g - s * s) / (2 * g);
  double sn = std::sqrt(std::max(0.0, 1 - c * c)), phi = 2 * kPi * u2;
  double x = sn * std::cos(phi), y = sn * std::sin(phi);
  return vec3_make(float(x * t.x + y * b.x + c * wo.x), float(x * t.y + y * b.y + c * wo.y), float(x * t.z + y * b.z + c * wo.z));
}

double rel(double a, double b) { return std::fabs(a - b) / std::max(std::fabs(b), 1e-30); }
double dist(st_vec3 a, st_vec3 b) { return std::sqrt(one_minus_cos(to_d3(a), to_d3(b)) * 2); }

}  // namespace

TEST(GuidingOpenCL, DeviceMatchesHost) {
  using namespace spectrack;
  const int n = 1 << 20;
  const float alpha = 0.6f, g_hg = 0.6f;
  const D3 wo = unit(0.2, 0.1, 1), light = unit(-0.7, 0.6, 0.3), axis = unit(0.3, -0.5, 0.81);
  const D3 away = {-light[0], -light[1], -light[2]};
  const st_vmf_mixture m = make_mixture({{away, 50, 0.7}, {unit(0, -1, 0.1), 300, 0.3}, {axis, 1e4, 0.2}, {wo, 1e-5, 0.1}});
  const st_vec3 mu = to_vec3(axis);
  std::vector<cl_float4> dirs(n), us(n);
  Uniforms u(77);
  for (int i = 0; i < n; ++i) {  // kappa log-uniform in [1e-5, 1e4] (and 0), directions within its lobe
    float kappa = i % 64 == 0 ? 0.0f : float(std::pow(10.0, -5 + 9 * double(u.next())));
    st_vec3 d = vmf_sample(mu, kappa, u.next(), u.next());
    dirs[i] = {{d.x, d.y, d.z, kappa}};
    us[i] = {{u.next(), u.next(), u.next(), 0.0f}};
  }
  DeviceInfo dev = select_device("");
  cl::Context ctx(dev.device);
  ProgramBuild pb = build_program(ctx, dev, probe_source(), "-cl-std=CL1.2", true);
  cl::CommandQueue q(ctx, dev.device);
  auto in = [&](const void* p, size_t bytes) { return cl::Buffer(ctx, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, bytes, const_cast<void*>(p)); };
  cl::Buffer bm = in(&m, sizeof m), bd = in(dirs.data(), n * sizeof(cl_float4)), bu = in(us.data(), n * sizeof(cl_float4));
  cl::Buffer bpdf(ctx, CL_MEM_WRITE_ONLY, n * 4), blobe(ctx, CL_MEM_WRITE_ONLY, n * 4), bf(ctx, CL_MEM_WRITE_ONLY, n * 4);
  cl::Buffer bvmf(ctx, CL_MEM_WRITE_ONLY, n * 16), bg(ctx, CL_MEM_WRITE_ONLY, n * 16);
  cl::Kernel k(pb.program, "k_guiding_probe");
  cl_float4 wo4 = {{float(wo[0]), float(wo[1]), float(wo[2]), 0}}, mu4 = {{mu.x, mu.y, mu.z, 0}};
  int a = 0;
  for (const cl::Buffer* b : {&bm, &bd, &bu}) k.setArg(a++, *b);
  k.setArg(a++, alpha), k.setArg(a++, g_hg), k.setArg(a++, wo4), k.setArg(a++, mu4), k.setArg(a++, cl_uint(n));
  for (const cl::Buffer* b : {&bpdf, &blobe, &bvmf, &bg, &bf}) k.setArg(a++, *b);
  q.enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange(n));
  std::vector<float> pdf(n), lobe(n), f(n);
  std::vector<cl_float4> vmf(n), guided(n);
  q.enqueueReadBuffer(bpdf, CL_TRUE, 0, n * 4, pdf.data());
  q.enqueueReadBuffer(blobe, CL_TRUE, 0, n * 4, lobe.data());
  q.enqueueReadBuffer(bf, CL_TRUE, 0, n * 4, f.data());
  q.enqueueReadBuffer(bvmf, CL_TRUE, 0, n * 16, vmf.data());
  q.enqueueReadBuffer(bg, CL_TRUE, 0, n * 16, guided.data());

  auto g = [&](const D3& w) { return 0.2 + 5 * std::exp(12 * (dot(w, light) - 1)); };
  double worst[5] = {0, 0, 0, 0, 0}, s = 0, s2 = 0;
  for (int i = 0; i < n; ++i) {
    const st_vec3 d = vec3_make(dirs[i].s[0], dirs[i].s[1], dirs[i].s[2]);
    const float kappa = dirs[i].s[3], u0 = us[i].s[0], u1 = us[i].s[1], u2 = us[i].s[2];
    worst[0] = std::max(worst[0], rel(pdf[i], vmf_mixture_pdf(&m, d)));
    if (vmf_eval(mu, kappa, d) > 1e-30f) worst[1] = std::max(worst[1], rel(lobe[i], vmf_eval(mu, kappa, d)));
    worst[2] = std::max(worst[2], dist(vec3_make(vmf[i].s[0], vmf[i].s[1], vmf[i].s[2]), vmf_sample(mu, kappa, u1, u2)));
    const st_vec3 wd = vec3_make(guided[i].s[0], guided[i].s[1], guided[i].s[2]);
    float u_reuse;
    st_vec3 wh = guide_choose(alpha, u0, &u_reuse) ? vmf_mixture_sample(&m, u_reuse, u1, u2) : hg_sample_in_device_frame(g_hg, to_vec3(wo), u1, u2);
    worst[3] = std::max(worst[3], dist(wd, wh));
    const D3 w = to_d3(wd);
    const double fh = hg(g_hg, dot(wo, w) / std::sqrt(dot(w, w)));
    worst[4] = std::max({worst[4], rel(f[i], fh), rel(guided[i].s[3], guide_mixture_pdf(alpha, vmf_mixture_pdf(&m, wd), f[i]))});
    double x = double(f[i]) / guided[i].s[3] * g(w);
    s += x, s2 += x * x;
  }
  EXPECT_LT(worst[0], 2e-6) << "mixture pdf, device vs host";
  EXPECT_LT(worst[1], 2e-6) << "lobe pdf, device vs host";
  EXPECT_LT(worst[2], 2e-6) << "vMF sample, device vs host (distance)";
  EXPECT_LT(worst[3], 2e-6) << "guided direction, device vs host (distance; the host samples the phase branch in double)";
  EXPECT_LT(worst[4], 5e-6) << "guided pdf and phase value at the device's direction";
  const double mean = s / n, se = std::sqrt((s2 / n - mean * mean) / (n - 1)), reference = phase_times_g(g_hg, wo, g);
  EXPECT_NEAR(mean, reference, 4 * se) << "the device's guided estimator with a guide pointing away";
  EXPECT_GT(std::fabs(mean / 1.03 - reference), 4 * se) << "twin: the pdf 3% off must be detected";
}

TEST(GuidingOpenCL, RendererProgramIncludesGuiding) {
  // the renderer's kernels read the guide cache where the feature mask has ST_FEATURE_GUIDING;
  // with guiding off images are unchanged (bench/bit_identity.sh, GuidingRender tests)
  const std::string src = spectrack::assemble_kernel_source({{"ST_KERNEL_MAX_MEDIA", "1"}});
  EXPECT_NE(src.find("st_vmf_mixture"), std::string::npos);
  EXPECT_NE(src.find("ST_HAS_GUIDING"), std::string::npos);
  EXPECT_NE(probe_source().find("st_vmf_mixture"), std::string::npos);
}
