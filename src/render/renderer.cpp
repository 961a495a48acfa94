// renderer.cpp: scene upload and the wavefront stage loop (see renderer.h for the design).
// Set-up order: resolve options, check the tracker against the media, choose the device, load
// grids and build majorant grids, fill st_scene, build kernels (cached), allocate, upload. Each
// launch goes through Impl::launch, which names it and records its OpenCL profiling time.
// What a scene lacks costs nothing: the kernels are compiled for the scene's st_feature mask
// (scene_features(); --generic-kernels compiles every feature and ST_MAX_MEDIA media), a scene
// without lights gets no shadow-ray buffer or queue, and one whose escaping rays see no light gets
// no escape launch (track sends them straight to finish).
#include "render/renderer.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <iostream>

#include "cl/opencl.h"
#include "image/image.h"
#include "volume/volume.h"

namespace spectrack {

namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

st_float4 f4(double x, double y, double z, double w = 0) { return st_float4{float(x), float(y), float(z), float(w)}; }
st_float4 f4(const Vec3& v, double w = 0) { return f4(v[0], v[1], v[2], w); }

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

Mat4 inverse_affine(const Mat4& a, const std::string& what) {
  // inverse of [A t; 0 1] = [A^-1, -A^-1 t; 0 1]
  const double(*m)[4] = a.m;
  double det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
               m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
  if (!(std::abs(det) > 1e-300) || !std::isfinite(det)) throw Error(what + ": transform is singular (zero scale?)");
  Mat4 r;
  double inv[3][3];
  inv[0][0] = (m[1][1] * m[2][2] - m[1][2] * m[2][1]) / det;
  inv[0][1] = (m[0][2] * m[2][1] - m[0][1] * m[2][2]) / det;
  inv[0][2] = (m[0][1] * m[1][2] - m[0][2] * m[1][1]) / det;
  inv[1][0] = (m[1][2] * m[2][0] - m[1][0] * m[2][2]) / det;
  inv[1][1] = (m[0][0] * m[2][2] - m[0][2] * m[2][0]) / det;
  inv[1][2] = (m[0][2] * m[1][0] - m[0][0] * m[1][2]) / det;
  inv[2][0] = (m[1][0] * m[2][1] - m[1][1] * m[2][0]) / det;
  inv[2][1] = (m[0][1] * m[2][0] - m[0][0] * m[2][1]) / det;
  inv[2][2] = (m[0][0] * m[1][1] - m[0][1] * m[1][0]) / det;
  for (int i = 0; i < 3; ++i) {
    double t = 0;
    for (int j = 0; j < 3; ++j) {
      r.m[i][j] = inv[i][j];
      t -= inv[i][j] * m[j][3];
    }
    r.m[i][3] = t;
  }
  return r;
}

// scale, then rotations about x, y, z, then translate (SCENE_FORMAT.md)
Mat4 user_transform(const TransformDesc& t) {
  Mat4 S, Rx, Ry, Rz, T;
  for (int i = 0; i < 3; ++i) S.m[i][i] = t.scale[i];
  const double k = M_PI / 180.0;
  double cx = std::cos(t.rotate_deg[0] * k), sx = std::sin(t.rotate_deg[0] * k);
  double cy = std::cos(t.rotate_deg[1] * k), sy = std::sin(t.rotate_deg[1] * k);
  double cz = std::cos(t.rotate_deg[2] * k), sz = std::sin(t.rotate_deg[2] * k);
  Rx.m[1][1] = cx; Rx.m[1][2] = -sx; Rx.m[2][1] = sx; Rx.m[2][2] = cx;
  Ry.m[0][0] = cy; Ry.m[0][2] = sy; Ry.m[2][0] = -sy; Ry.m[2][2] = cy;
  Rz.m[0][0] = cz; Rz.m[0][1] = -sz; Rz.m[1][0] = sz; Rz.m[1][1] = cz;
  for (int i = 0; i < 3; ++i) T.m[i][3] = t.translate[i];
  return T * Rz * Ry * Rx * S;
}

Vec3 normalize(Vec3 v) {
  double l = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
  return {v[0] / l, v[1] / l, v[2] / l};
}
Vec3 cross(const Vec3& a, const Vec3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}

bool achromatic(const Vec3& v) { return v[0] == v[1] && v[1] == v[2]; }

struct LaunchRecord {
  std::string name;
  cl::Event event;
};

}  // namespace

struct Renderer::Impl {
  SceneDesc scene;
  RenderOptions opt;
  DeviceInfo dev;
  cl::Context ctx;
  cl::CommandQueue queue;
  cl::Program program;
  std::map<std::string, cl::Kernel> kernels;
  st_scene st{};
  uint32_t features = ST_FEATURES_ALL;
  Clock::time_point t_created = Clock::now();
  double seconds_setup = 0, seconds_build = 0;
  bool from_cache = false;
  int tracker = 0, scheme = 0, spp = 0;
  uint32_t seed = 0;

  std::vector<uint32_t> grid_words;
  std::vector<float> maj_cells;  // (dmax, dmin) pairs
  std::vector<float> env_data;
  cl::Buffer b_scene, b_grids, b_maj, b_env;
  std::vector<LaunchRecord> pending;
  std::map<std::string, KernelTime> kernel_times;

  cl::Kernel& kernel(const std::string& name) {
    auto it = kernels.find(name);
    if (it != kernels.end()) return it->second;
    cl_int err = CL_SUCCESS;
    cl::Kernel k(program, name.c_str(), &err);
    ST_CL_CHECK(err, ("clCreateKernel(" + name + ")").c_str());
    return kernels[name] = k;
  }

  cl::Buffer buffer(cl_mem_flags flags, size_t bytes, const void* host, const char* what) {
    cl_int err = CL_SUCCESS;
    // never allocate 0 bytes; a host copy shorter than that is padded, never over-read
    std::vector<unsigned char> padded;
    if (bytes < 16) {
      if (host) {
        padded.assign(16, 0);
        std::memcpy(padded.data(), host, bytes);
        host = padded.data();
      }
      bytes = 16;
    }
    if (bytes > dev.max_alloc)
      throw Error(fmt::format("{} needs {:.1f} MiB in one buffer but device '{}' allows at most {:.1f} MiB per "
                              "allocation (global memory {:.1f} MiB); choose another device with --device",
                              what, bytes / 1048576.0, dev.name, dev.max_alloc / 1048576.0, dev.global_mem / 1048576.0));
    cl::Buffer b(ctx, flags | (host ? CL_MEM_COPY_HOST_PTR : 0), bytes, const_cast<void*>(host), &err);
    ST_CL_CHECK(err, (std::string("clCreateBuffer(") + what + ")").c_str());
    return b;
  }

  // Enqueues a named 1D launch of n items and keeps its event for profiling.
  void launch(const std::string& name, size_t n) {
    if (n == 0) return;
    // A fixed work-group size: PoCL JIT-compiles a kernel once per work-group size, so letting the
    // driver choose one per item count would recompile on most launches.
    const size_t local = 64;
    size_t global = (n + local - 1) / local * local;
    cl::Event ev;
    cl_int err = queue.enqueueNDRangeKernel(kernel(name), cl::NullRange, cl::NDRange(global),
                                            cl::NDRange(local), nullptr, &ev);
    ST_CL_CHECK(err, ("clEnqueueNDRangeKernel(" + name + ")").c_str());
    pending.push_back({name, ev});
  }

  void collect_profiling() {
    for (auto& r : pending) {
      cl_ulong a = 0, b = 0;
      if (r.event.getProfilingInfo(CL_PROFILING_COMMAND_START, &a) == CL_SUCCESS &&
          r.event.getProfilingInfo(CL_PROFILING_COMMAND_END, &b) == CL_SUCCESS && b >= a) {
        kernel_times[r.name].seconds += double(b - a) * 1e-9;
      }
      kernel_times[r.name].launches += 1;
    }
    pending.clear();
  }

  void setup();
  uint32_t scene_features() const;
  // Shadow-ray slots per path: one per light, none (no buffer, no queue) without lights.
  uint32_t shadow_lights() const { return uint32_t(st.n_lights); }
  // Batches in flight (a ring of result buffers): more than two keep the slots busy while a
  // batch's longest paths finish; capped by ST_MAX_BATCHES_IN_FLIGHT, the batch count and
  // 32-bit result indices. Written to st.batches_in_flight before the first launch.
  // Paths per batch (rounded up to whole samples): 2Q with two batches in flight, so one batch
  // fills the slots while the other finishes; Q with the ring, so the first pass is done sooner.
  uint64_t batch_target_paths(uint64_t Q) const {
    return (opt.batches_in_flight > 0 && opt.batches_in_flight <= 2) ? 2 * Q : Q;
  }
  // Batches that may be issued beyond the accumulated ones: the first batch alone (its longest
  // paths finish sooner without later batches sharing the device, so the first pass, a preview,
  // is on the film early), then the whole ring.
  static uint64_t batches_ahead(uint64_t accumulated, uint64_t K) { return accumulated == 0 ? 1 : K; }
  uint64_t batches_in_flight(uint64_t batch_paths, uint64_t n_batches) {
    uint64_t k = opt.batches_in_flight > 0 ? uint64_t(opt.batches_in_flight) : uint64_t(ST_MAX_BATCHES_IN_FLIGHT);
    k = std::min<uint64_t>({k, uint64_t(ST_MAX_BATCHES_IN_FLIGHT), std::max<uint64_t>(1, n_batches)});
    while (k > 1 && k * batch_paths >= (uint64_t(1) << 32)) --k;
    if (st.batches_in_flight != int(k)) {
      st.batches_in_flight = int(k);
      ST_CL_CHECK(queue.enqueueWriteBuffer(b_scene, CL_TRUE, 0, sizeof(st), &st), "write scene constants");
    }
    return k;
  }
  void record_occupancy(RenderStats& S, const uint64_t* n_q, uint64_t Q) const;
  // Construction to the first batch on the film (waits for the accumulation launch).
  double first_pass_seconds() {
    ST_CL_CHECK(queue.finish(), "finish first pass");
    return seconds_since(t_created);
  }
  void add_medium(int i, const MediumDesc& m);
  void add_light(int i, const LightDesc& l);
  void set_camera();
  RenderResult render(int64_t sample_begin, int spp);
  template <typename T>
  std::vector<T> run_probe(const std::string& name, size_t n, const std::function<void(cl::Kernel&, cl::Buffer&)>& args);
};

void Renderer::Impl::add_medium(int i, const MediumDesc& md) {
  st_medium& m = st.media[i];
  std::memset(&m, 0, sizeof(m));
  std::string ctx_name = scene.path + ": " + md.json_path;
  m.type = md.type;
  m.phase_type = md.phase.type;
  m.g = float(md.phase.g);
  m.majorant_scale = float(md.majorant_scale);
  m.minorant_scale = float(md.minorant_scale);
  m.sigma_a = f4(md.sigma_a[0] * md.density_scale, md.sigma_a[1] * md.density_scale, md.sigma_a[2] * md.density_scale);
  m.sigma_s = f4(md.sigma_s[0] * md.density_scale, md.sigma_s[1] * md.density_scale, md.sigma_s[2] * md.density_scale);
  m.density_grid = ST_NO_GRID;
  m.emission_grid = ST_NO_GRID;
  if (md.emission.present) {
    Vec3 r = md.emission.radiance;
    m.Le = f4(r[0] * md.emission.scale, r[1] * md.emission.scale, r[2] * md.emission.scale);
    m.emissive = (m.Le.x > 0 || m.Le.y > 0 || m.Le.z > 0) ? 1 : 0;
  }
  m.maj_offset = uint32_t(maj_cells.size() / 2);

  auto upload_grid = [&](const GridData& g) {
    uint32_t offset = uint32_t(grid_words.size());
    size_t bytes = g.handle.size();
    size_t words = (bytes + 7) / 8 * 2;
    grid_words.resize(grid_words.size() + words, 0u);
    std::memcpy(grid_words.data() + offset, g.handle.data(), bytes);
    if (grid_words.size() > (size_t(1) << 30))
      throw Error(ctx_name + ": volumes exceed 4 GiB of NanoVDB data, which 32-bit addressing cannot reach");
    return offset;
  };

  if (md.type == ST_MEDIUM_HOMOGENEOUS) {
    const auto& lo = md.bounds[0];
    const auto& hi = md.bounds[1];
    for (int r = 0; r < 3; ++r) {
      double s = 1.0 / (hi[r] - lo[r]);
      float row[4] = {0, 0, 0, float(-lo[r] * s)};
      row[r] = float(s);
      m.world_to_index[r] = st_float4{row[0], row[1], row[2], row[3]};
    }
    m.maj_origin = f4(0, 0, 0, 1);
    m.maj_dims[0] = m.maj_dims[1] = m.maj_dims[2] = 1;
    maj_cells.push_back(1.0f);
    maj_cells.push_back(1.0f);
    return;
  }

  GridData g = load_float_grid(md.file, md.grid, md.grid_index, ctx_name);
  Mat4 i2w;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) i2w.m[r][c] = g.index_to_world[r][c];
  Mat4 w2i = inverse_affine(user_transform(md.transform) * i2w, ctx_name + "/transform");
  for (int r = 0; r < 3; ++r) m.world_to_index[r] = f4(w2i.m[r][0], w2i.m[r][1], w2i.m[r][2], w2i.m[r][3]);
  MajorantGrid mg = build_majorant_grid(g, opt.majorant_cell);
  m.maj_origin = f4(mg.origin[0], mg.origin[1], mg.origin[2], mg.cell);
  for (int a = 0; a < 3; ++a) m.maj_dims[a] = mg.dims[a];
  for (size_t c = 0; c < mg.dmax.size(); ++c) {
    maj_cells.push_back(mg.dmax[c]);
    maj_cells.push_back(mg.dmin[c]);
  }
  // a coarse level only pays when the grid spans more than one block
  const int B = opt.majorant_block;
  if (B > 1 && std::max({mg.dims[0], mg.dims[1], mg.dims[2]}) > B) {
    MajorantGrid coarse = coarsen_majorant_grid(mg, B);
    m.maj_block = B;
    m.maj_coarse_offset = uint32_t(maj_cells.size() / 2);
    for (size_t c = 0; c < coarse.dmax.size(); ++c) {
      maj_cells.push_back(coarse.dmax[c]);
      maj_cells.push_back(coarse.dmin[c]);
    }
  }
  m.density_grid = upload_grid(g);
  if (md.emission.present && !md.emission.grid.empty() && m.emissive) {
    GridData e = load_float_grid(md.file, md.emission.grid, -1, ctx_name + "/emission");
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c)
        if (std::abs(e.index_to_world[r][c] - g.index_to_world[r][c]) > 1e-6 * (1 + std::abs(g.index_to_world[r][c])))
          throw Error(fmt::format("{}/emission/grid: grid '{}' has a different index-to-world transform than density "
                                  "grid '{}'; both grids must share one transform",
                                  ctx_name, md.emission.grid, md.grid));
    m.emission_grid = upload_grid(e);
  }
}

void Renderer::Impl::add_light(int i, const LightDesc& ld) {
  st_light& l = st.lights[i];
  std::memset(&l, 0, sizeof(l));
  l.type = ld.type;
  if (ld.type == ST_LIGHT_DIRECTIONAL) {
    Vec3 d = normalize(ld.to_light);
    l.direction = f4(d);
    double half = ld.angle_deg * 0.5 * M_PI / 180.0;
    if (half <= 0) {
      l.is_delta = 1;
      l.radiance = f4(ld.irradiance);
      l.cos_max = 1.0f;
    } else {
      // a uniform disc of angular radius `half` gives irradiance E = L * pi * sin^2(half)
      double s2 = std::sin(half) * std::sin(half);
      double L = 1.0 / (M_PI * s2);
      l.radiance = f4(ld.irradiance[0] * L, ld.irradiance[1] * L, ld.irradiance[2] * L);
      l.cos_max = float(std::cos(half));
      l.pdf_cone = float(1.0 / (2.0 * M_PI * (1.0 - std::cos(half))));
    }
    return;
  }
  if (ld.map.empty()) {
    l.type = ST_LIGHT_ENV_UNIFORM;
    l.radiance = f4(ld.radiance);
    return;
  }
  l.type = ST_LIGHT_ENV_MAP;
  RgbImage img;
  try {
    img = read_image(ld.map);
  } catch (const Error& e) {
    throw Error(fmt::format("{}: {}/map: {}", scene.path, ld.json_path, e.what()));
  }
  for (float v : img.rgb)
    if (!std::isfinite(v) || v < 0)
      throw Error(fmt::format("{}: {}/map: {}: negative or non-finite texel", scene.path, ld.json_path, ld.map));
  l.radiance = f4(ld.scale, ld.scale, ld.scale);
  l.map_width = img.width;
  l.map_height = img.height;
  l.map_offset = uint32_t(env_data.size());
  for (size_t p = 0; p < size_t(img.width) * img.height; ++p) {
    for (int c = 0; c < 3; ++c) env_data.push_back(img.rgb[p * 3 + c]);
    env_data.push_back(0.0f);
  }
  // sampling distribution: f(u, v) = max(rgb) * sin(theta), piecewise constant per texel
  int W = img.width, H = img.height;
  std::vector<double> row_sum(H, 0.0);
  std::vector<double> f(size_t(W) * H);
  for (int y = 0; y < H; ++y) {
    double s = std::sin(M_PI * (y + 0.5) / H);
    for (int x = 0; x < W; ++x) {
      const float* px = &img.rgb[(size_t(y) * W + x) * 3];
      f[size_t(y) * W + x] = std::max({px[0], px[1], px[2]}) * s;
      row_sum[y] += f[size_t(y) * W + x];
    }
  }
  double total = 0;
  for (double r : row_sum) total += r;
  l.cdf_offset = uint32_t(env_data.size());
  l.map_integral = float(total / (double(W) * H));
  double acc = 0;
  env_data.push_back(0.0f);
  for (int y = 0; y < H; ++y) {
    acc += row_sum[y];
    env_data.push_back(total > 0 ? float(acc / total) : float(y + 1) / H);
  }
  env_data[l.cdf_offset + H] = 1.0f;
  for (int y = 0; y < H; ++y) {
    double a = 0;
    size_t base = env_data.size();
    env_data.push_back(0.0f);
    for (int x = 0; x < W; ++x) {
      a += f[size_t(y) * W + x];
      env_data.push_back(row_sum[y] > 0 ? float(a / row_sum[y]) : float(x + 1) / W);
    }
    env_data[base + W] = 1.0f;
  }
}

void Renderer::Impl::set_camera() {
  const CameraDesc& c = scene.camera;
  st_camera& cam = st.camera;
  cam.type = c.type;
  cam.width = scene.film.width;
  cam.height = scene.film.height;
  Vec3 fwd = normalize({c.look_at[0] - c.position[0], c.look_at[1] - c.position[1], c.look_at[2] - c.position[2]});
  Vec3 right = normalize(cross(fwd, c.up));
  Vec3 up = cross(right, fwd);
  double shorter = std::min(cam.width, cam.height);
  double half = c.type == ST_CAMERA_ORTHOGRAPHIC ? 0.5 * c.height : std::tan(0.5 * c.fov_deg * M_PI / 180.0);
  double sx = half * cam.width / shorter, sy = half * cam.height / shorter;
  cam.position = f4(c.position);
  cam.forward = f4(fwd);
  cam.right = f4(right[0] * sx, right[1] * sx, right[2] * sx);
  cam.up = f4(up[0] * sy, up[1] * sy, up[2] * sy);
}

void Renderer::Impl::setup() {
  auto t0 = Clock::now();
  tracker = opt.tracker >= 0 ? opt.tracker : scene.render.tracker;
  scheme = opt.scheme >= 0 ? opt.scheme : scene.render.scheme;
  spp = opt.spp > 0 ? opt.spp : scene.film.spp;
  seed = opt.seed >= 0 ? uint32_t(opt.seed) : scene.render.seed;
  if (tracker == ST_TRACKER_DELTA) {
    for (auto& m : scene.media)
      if (!achromatic(m.sigma_a) || !achromatic(m.sigma_s))
        throw Error(fmt::format("{}: {}: tracker 'delta' needs achromatic media (equal sigma_a and sigma_s in every "
                                "channel); medium '{}' is chromatic: use delta-per-channel or spectral",
                                scene.path, m.json_path, m.name));
  }
  if (opt.iteration_budget < 1) throw Error("iteration budget must be at least 1");
  if (opt.majorant_cell < 1) throw Error("majorant cell must be at least 1 voxel");
  if (opt.majorant_block < 0) throw Error("majorant block must be 0 (one level) or at least 1 cell");

  dev = select_device(opt.device);
  cl_int err = CL_SUCCESS;
  ctx = cl::Context(dev.device, nullptr, nullptr, nullptr, &err);
  ST_CL_CHECK(err, "clCreateContext");
  queue = cl::CommandQueue(ctx, dev.device, CL_QUEUE_PROFILING_ENABLE, &err);
  ST_CL_CHECK(err, "clCreateCommandQueue");

  std::memset(&st, 0, sizeof(st));
  st.n_media = int(scene.media.size());
  st.n_lights = int(scene.lights.size());
  for (int i = 0; i < st.n_media; ++i) add_medium(i, scene.media[i]);
  for (int i = 0; i < st.n_lights; ++i) add_light(i, scene.lights[i]);
  set_camera();
  st.tracker = tracker;
  st.scheme = scheme;
  st.max_depth = scene.render.max_depth;
  st.seed = seed;
  st.n_channels_per_sample = (tracker == ST_TRACKER_DELTA_PER_CHANNEL || tracker == ST_TRACKER_DECOMPOSITION) ? 3 : 1;
  st.iteration_budget = opt.iteration_budget;
  st.batches_in_flight = 2;  // set per render (batches_in_flight())
  {
    auto [x0, x1, y0, y1] = opt.pixel_bounds;
    if (x1 < 0) x0 = 0, x1 = scene.film.width, y0 = 0, y1 = scene.film.height;
    if (!(0 <= x0 && x0 < x1 && x1 <= scene.film.width && 0 <= y0 && y0 < y1 && y1 <= scene.film.height))
      throw Error(fmt::format("pixel bounds {},{},{},{} (x0,x1,y0,y1) are not a non-empty window of the {}x{} film",
                              x0, x1, y0, y1, scene.film.width, scene.film.height));
    st.pixel_x0 = x0;
    st.pixel_y0 = y0;
    st.window_width = x1 - x0;
    st.window_height = y1 - y0;
  }
  for (auto& l : scene.lights) st.has_env |= (l.type != ST_LIGHT_DIRECTIONAL);
  for (auto& m : scene.media) st.chromatic |= !(achromatic(m.sigma_a) && achromatic(m.sigma_s));
  if (maj_cells.empty()) maj_cells = {0.0f, 0.0f};
  if (grid_words.empty()) grid_words = {0u, 0u};
  if (env_data.empty()) env_data = {0.0f};

  auto tb = Clock::now();
  // the feature mask is in the source, hence in the kernel-cache key
  features = opt.generic_kernels ? uint32_t(ST_FEATURES_ALL) : scene_features();
  const int max_media = opt.generic_kernels ? ST_MAX_MEDIA : std::max(1, st.n_media);
  std::string src = assemble_kernel_source({{"ST_KERNEL_MAX_MEDIA", std::to_string(max_media)},
                                            {"ST_FEATURES", fmt::format("0x{:x}u", features)}});
  std::string options = "-cl-std=CL1.2";
  ProgramBuild pb = build_program(ctx, dev, src, options, opt.quiet);
  program = pb.program;
  from_cache = pb.from_cache;
  seconds_build = seconds_since(tb);

  b_scene = buffer(CL_MEM_READ_ONLY, sizeof(st), &st, "scene constants");
  b_grids = buffer(CL_MEM_READ_ONLY, grid_words.size() * 4, grid_words.data(), "NanoVDB grids");
  b_maj = buffer(CL_MEM_READ_ONLY, maj_cells.size() * 4, maj_cells.data(), "majorant grids");
  b_env = buffer(CL_MEM_READ_ONLY, env_data.size() * 4, env_data.data(), "environment maps");
  if (sizeof(st) > dev.max_constant)
    throw Error(fmt::format("device '{}' has {} bytes of constant memory; spectrack needs {}", dev.name,
                            dev.max_constant, sizeof(st)));
  seconds_setup = seconds_since(t0);
}

uint32_t Renderer::Impl::scene_features() const {
  uint32_t f = 0;
  if (st.n_media > 1) f |= ST_FEATURE_MULTI_MEDIUM;
  for (int i = 0; i < st.n_media; ++i) {
    const st_medium& m = st.media[i];
    if (m.emissive) f |= ST_FEATURE_EMISSION;
    // exactly what the kernels see: the float coefficients
    bool gray = m.sigma_a.x == m.sigma_a.y && m.sigma_a.y == m.sigma_a.z && m.sigma_s.x == m.sigma_s.y &&
                m.sigma_s.y == m.sigma_s.z;
    if (!gray) f |= ST_FEATURE_CHROMATIC;
    if (m.phase_type == ST_PHASE_HG) f |= ST_FEATURE_HG;
    if (m.type == ST_MEDIUM_VDB) f |= ST_FEATURE_VDB;
    if (m.maj_block > 0) f |= ST_FEATURE_COARSE_MAJORANT;
  }
  for (int i = 0; i < st.n_lights; ++i) {
    const st_light& l = st.lights[i];
    if (l.type == ST_LIGHT_ENV_MAP) f |= ST_FEATURE_ENV_MAP;
    if (l.type != ST_LIGHT_DIRECTIONAL || !l.is_delta) f |= ST_FEATURE_ESCAPE;
  }
  if (tracker == ST_TRACKER_DECOMPOSITION || tracker == ST_TRACKER_SPECTRAL_DECOMPOSITION) f |= ST_FEATURE_DECOMPOSITION;
  return f;
}

void Renderer::Impl::record_occupancy(RenderStats& S, const uint64_t* n_q, uint64_t Q) const {
  uint64_t busy = 0;
  for (int q = ST_Q_TRACK; q < ST_Q_SHADOW; ++q) busy += n_q[q];  // path slots (shadow rays are per light)
  double occ = double(busy) / double(Q);
  // running mean over the iterations recorded so far (S.iterations counts this one)
  S.occupancy_mean += (occ - S.occupancy_mean) / double(S.iterations);
  S.occupancy_min = S.iterations == 1 ? occ : std::min(S.occupancy_min, occ);
  if (occ < 0.5) S.iterations_below_half++;
}

template <typename T>
std::vector<T> Renderer::Impl::run_probe(const std::string& name, size_t n,
                                         const std::function<void(cl::Kernel&, cl::Buffer&)>& args) {
  std::vector<T> out(n);
  if (n == 0) return out;
  cl::Buffer b_out = buffer(CL_MEM_WRITE_ONLY, n * sizeof(T), nullptr, "probe output");
  cl::Kernel& k = kernel(name);
  args(k, b_out);
  launch(name, n);
  ST_CL_CHECK(queue.enqueueReadBuffer(b_out, CL_TRUE, 0, n * sizeof(T), out.data()), ("read " + name).c_str());
  collect_profiling();
  return out;
}

RenderResult Renderer::Impl::render(int64_t sample_begin, int spp) {
  auto t_start = Clock::now();
  if (sample_begin < 0 || spp < 1 || uint64_t(sample_begin) + uint64_t(spp) > (uint64_t(1) << 32))
    throw Error(fmt::format("sample range {}:{} is not a non-empty range of sample indices 0 .. 2^32",
                            sample_begin, sample_begin + spp));
  RenderResult res;
  res.width = st.window_width;
  res.height = st.window_height;
  res.full_width = scene.film.width;
  res.full_height = scene.film.height;
  res.x0 = st.pixel_x0;
  res.y0 = st.pixel_y0;
  res.sample_begin = sample_begin;
  res.spp_requested = spp;
  res.tracker = tracker;
  res.scheme = scheme;
  res.seed = seed;
  res.device = dev.name;
  res.seconds_setup = seconds_setup;
  res.seconds_build = seconds_build;
  res.kernels_from_cache = from_cache;
  res.features = features;
  kernel_times.clear();

  const uint32_t NL = shadow_lights();
  const uint64_t npix = uint64_t(st.window_width) * st.window_height;
  const uint64_t nch = uint64_t(st.n_channels_per_sample);
  uint64_t Q = opt.path_slots > 0 ? uint64_t(opt.path_slots) : ((dev.type & CL_DEVICE_TYPE_GPU) ? (1u << 20) : (1u << 16));
  const uint64_t total_paths = uint64_t(spp) * npix * nch;
  Q = std::max<uint64_t>(1, std::min<uint64_t>(Q, total_paths));
  uint64_t samples_per_batch = std::max<uint64_t>(1, (batch_target_paths(Q) + npix * nch - 1) / (npix * nch));
  samples_per_batch = std::min<uint64_t>(samples_per_batch, uint64_t(spp));
  const uint64_t batch_paths = samples_per_batch * npix * nch;
  if (batch_paths >= (uint64_t(1) << 32)) throw Error("film too large: one sample of every pixel exceeds 2^32 paths");
  const uint64_t n_batches = (uint64_t(spp) + samples_per_batch - 1) / samples_per_batch;
  auto batch_samples = [&](uint64_t b) { return std::min<uint64_t>(samples_per_batch, uint64_t(spp) - b * samples_per_batch); };

  // refuse what cannot fit before allocating anything
  const double need = double(Q) * (sizeof(st_path) + NL * sizeof(st_shadow) + 2 * (5 + NL) * 4) +
                      double(batches_in_flight(batch_paths, n_batches)) * batch_paths * sizeof(st_float4) + 2.0 * npix * sizeof(st_float4) +
                      grid_words.size() * 4.0 + maj_cells.size() * 4.0 + env_data.size() * 4.0;
  if (need > double(dev.global_mem))
    throw Error(fmt::format("this render needs about {:.1f} MiB of device memory ({}x{} film, {} paths in flight) "
                            "but device '{}' has {:.1f} MiB; use a smaller film, --path-slots, or another device "
                            "with --device",
                            need / 1048576.0, st.window_width, st.window_height, Q, dev.name, dev.global_mem / 1048576.0));
  cl::Buffer b_paths = buffer(CL_MEM_READ_WRITE, Q * sizeof(st_path), nullptr, "path states");
  cl::Buffer b_shadows = buffer(CL_MEM_READ_WRITE, Q * NL * sizeof(st_shadow), nullptr, "shadow rays");
  const uint64_t per_parity = 5 * Q + Q * NL;
  std::vector<uint32_t> init_queue(2 * per_parity, 0u);
  for (uint64_t i = 0; i < Q; ++i) init_queue[i] = uint32_t(i);  // parity 0, FREE
  cl::Buffer b_queues = buffer(CL_MEM_READ_WRITE, init_queue.size() * 4, init_queue.data(), "queues");
  std::vector<uint32_t> counters(ST_C_COUNT, 0u);
  cl::Buffer b_counters = buffer(CL_MEM_READ_WRITE, counters.size() * 4, counters.data(), "counters");
  const uint64_t K = batches_in_flight(batch_paths, n_batches);
  cl::Buffer b_results = buffer(CL_MEM_READ_WRITE, K * batch_paths * sizeof(st_float4), nullptr, "batch results");
  // film: per pixel the running sum, then (second half) its Kahan compensation term
  std::vector<st_float4> film(2 * npix, st_float4{0, 0, 0, 0});
  cl::Buffer b_film = buffer(CL_MEM_READ_WRITE, film.size() * sizeof(st_float4), film.data(), "film");

  // launch order within an iteration, and the queue each stage reads
  const char* stage_kernels[] = {"k_raygen", "k_track", "k_escape", "k_scatter", "k_shadow", "k_finish"};
  const int stage_queue[] = {ST_Q_FREE, ST_Q_TRACK, ST_Q_ESCAPE, ST_Q_SCATTER, ST_Q_SHADOW, ST_Q_FINISH};
  for (const char* name : stage_kernels) {
    cl::Kernel& k = kernel(name);
    int a = 0;
    k.setArg(a++, b_scene);
    k.setArg(a++, b_grids);
    k.setArg(a++, b_maj);
    k.setArg(a++, b_env);
    k.setArg(a++, b_paths);
    k.setArg(a++, b_shadows);
    k.setArg(a++, b_queues);
    k.setArg(a++, b_counters);
    k.setArg(a++, b_results);
    k.setArg(a++, cl_uint(Q));
    k.setArg(a++, cl_uint(NL));
  }
  cl::Kernel& k_acc = kernel("k_accumulate");
  k_acc.setArg(0, b_results);
  k_acc.setArg(1, b_film);

  uint64_t n_q[ST_Q_COUNT] = {Q, 0, 0, 0, 0, 0};
  uint32_t cur = 0;
  uint64_t issued = 0, accumulated = 0, samples_done = 0;
  std::vector<uint64_t> batch_done(K, 0);
  uint64_t batches_target = n_batches;
  bool stopping = false;
  RenderStats& S = res.stats;
  std::vector<uint32_t> zeros(ST_C_COUNT, 0u);
  uint32_t max_bits = 0;

  const char* trace_env = std::getenv("SPECTRACK_TRACE_QUEUES");
  const bool trace_queues = trace_env && std::string(trace_env) != "0";
  auto t_loop = Clock::now();
  while (accumulated < batches_target) {
    if (!stopping && opt.stop && opt.stop->load()) {
      stopping = true;
      batches_target = std::max<uint64_t>(accumulated, issued / batch_paths);  // only fully issued batches
      if (batches_target == accumulated) break;
    }
    uint64_t issue_limit = std::min<uint64_t>(total_paths, (accumulated + batches_ahead(accumulated, K)) * batch_paths);
    issue_limit = std::min<uint64_t>(issue_limit, batches_target * batch_paths);
    uint64_t n_new = std::min<uint64_t>(n_q[ST_Q_FREE], issue_limit > issued ? issue_limit - issued : 0);
    uint64_t in_flight = 0;
    for (int q = ST_Q_TRACK; q < ST_Q_COUNT; ++q) in_flight += n_q[q];
    if (n_new == 0 && in_flight == 0)
      throw Error(fmt::format("internal: wavefront stalled with {} of {} batches accumulated", accumulated, batches_target));

    for (int s = 0; s < 6; ++s) {
      cl::Kernel& k = kernel(stage_kernels[s]);
      k.setArg(11, cl_uint(cur));
      k.setArg(12, cl_uint(n_q[stage_queue[s]]));
    }
    cl::Kernel& kr = kernel("k_raygen");
    kr.setArg(13, cl_ulong(issued));
    kr.setArg(14, cl_uint(n_new));
    kr.setArg(15, cl_uint(batch_paths));
    kr.setArg(16, cl_uint(sample_begin));
    kr.setArg(17, cl_uint(samples_per_batch));
    for (int s = 0; s < 6; ++s) launch(stage_kernels[s], n_q[stage_queue[s]]);
    issued += n_new;
    ST_CL_CHECK(queue.enqueueReadBuffer(b_counters, CL_TRUE, 0, counters.size() * 4, counters.data()), "read counters");
    ST_CL_CHECK(queue.enqueueWriteBuffer(b_counters, CL_FALSE, 0, zeros.size() * 4, zeros.data()), "reset counters");
    collect_profiling();
    S.iterations++;

    for (int q = 0; q < ST_Q_COUNT; ++q) n_q[q] = counters[ST_C_QUEUE + q];
    record_occupancy(S, n_q, Q);
    cur = 1 - cur;
    if (trace_queues)
      std::cerr << fmt::format("iteration {}: issued {} free {} track {} escape {} scatter {} finish {} shadow {} "
                               "done {}+{} accumulated {}\n",
                               S.iterations, issued, n_q[ST_Q_FREE], n_q[ST_Q_TRACK], n_q[ST_Q_ESCAPE],
                               n_q[ST_Q_SCATTER], n_q[ST_Q_FINISH], n_q[ST_Q_SHADOW],
                               batch_done[0] + counters[ST_C_BATCH_DONE], K > 1 ? batch_done[1] + counters[ST_C_BATCH_DONE + 1] : 0,
                               accumulated);
    for (uint64_t r = 0; r < K; ++r) batch_done[r] += counters[ST_C_BATCH_DONE + r];
    S.lookups_track += counters[ST_C_LOOKUPS_TRACK];
    S.lookups_shadow += counters[ST_C_LOOKUPS_SHADOW];
    S.lookups_emission += counters[ST_C_LOOKUPS_EMISSION];
    S.real_collisions += counters[ST_C_REAL_COLLISIONS];
    S.null_collisions += counters[ST_C_NULL_COLLISIONS];
    S.control_collisions += counters[ST_C_CONTROL_COLLISIONS];
    S.residual_collisions += counters[ST_C_RESIDUAL_COLLISIONS];
    S.dda_steps += counters[ST_C_DDA_STEPS];
    S.dda_nonempty += counters[ST_C_DDA_NONEMPTY];
    S.requeues += counters[ST_C_REQUEUES];
    S.nonfinite_samples += counters[ST_C_NONFINITE];
    S.scatter_events += counters[ST_C_SCATTER_EVENTS];
    max_bits = std::max(max_bits, counters[ST_C_MAX_THROUGHPUT_BITS]);

    // add every completed batch to the film, in batch order
    while (accumulated < batches_target) {
      uint64_t b = accumulated;
      uint64_t expected = batch_samples(b) * npix * nch;
      if (batch_done[b % K] < expected) break;
      k_acc.setArg(2, cl_uint((b % K) * batch_paths));
      k_acc.setArg(3, cl_uint(batch_samples(b)));
      k_acc.setArg(4, cl_uint(npix));
      k_acc.setArg(5, cl_uint(nch));
      launch("k_accumulate", npix);
      batch_done[b % K] -= expected;
      samples_done += batch_samples(b);
      S.paths += expected;
      if (accumulated == 0) res.seconds_first_pass = first_pass_seconds();
      ++accumulated;
    }
    if (opt.progress) opt.progress(double(samples_done) / double(spp));
  }
  ST_CL_CHECK(queue.enqueueReadBuffer(b_film, CL_TRUE, 0, film.size() * sizeof(st_float4), film.data()), "read film");
  collect_profiling();
  res.seconds_render = seconds_since(t_loop);
  (void)t_start;

  float mt;
  std::memcpy(&mt, &max_bits, 4);
  S.max_throughput = mt;
  S.kernels = kernel_times;
  res.spp_done = int(samples_done);
  res.interrupted = samples_done < uint64_t(spp);
  res.rgb.assign(npix * 3, 0.0f);
  res.sum.assign(npix * 3, 0.0);
  for (uint64_t p = 0; p < npix; ++p) {
    // Kahan: the exact sum is (to float rounding of the terms) sum - compensation
    const st_float4& f = film[p];
    const st_float4& c = film[npix + p];
    res.sum[p * 3 + 0] = double(f.x) - double(c.x);
    res.sum[p * 3 + 1] = double(f.y) - double(c.y);
    res.sum[p * 3 + 2] = double(f.z) - double(c.z);
    for (int k = 0; k < 3 && samples_done > 0; ++k) res.rgb[p * 3 + k] = float(res.sum[p * 3 + k] / double(samples_done));
  }
  return res;
}

Renderer::Renderer(const SceneDesc& scene, const RenderOptions& options) : impl_(new Impl) {
  impl_->scene = scene;
  impl_->opt = options;
  impl_->setup();
}
Renderer::~Renderer() = default;

RenderResult Renderer::render() { return impl_->render(impl_->opt.sample_begin, impl_->spp); }
RenderResult Renderer::render(int64_t sample_begin, int spp) { return impl_->render(sample_begin, spp); }

const std::vector<std::pair<const char*, RenderStats::Counter>>& RenderStats::counters() {
  static const std::vector<std::pair<const char*, Counter>> list = {
      {"paths", &RenderStats::paths},
      {"density_lookups_tracking", &RenderStats::lookups_track},
      {"density_lookups_shadow", &RenderStats::lookups_shadow},
      {"emission_lookups", &RenderStats::lookups_emission},
      {"real_collisions", &RenderStats::real_collisions},
      {"null_collisions", &RenderStats::null_collisions},
      {"control_collisions", &RenderStats::control_collisions},
      {"residual_collisions", &RenderStats::residual_collisions},
      {"scatter_events", &RenderStats::scatter_events},
      {"dda_steps", &RenderStats::dda_steps},
      {"dda_steps_nonempty", &RenderStats::dda_nonempty},
      {"iterations_below_half_occupancy", &RenderStats::iterations_below_half},
      {"requeues", &RenderStats::requeues},
      {"iterations", &RenderStats::iterations},
      {"nonfinite_samples", &RenderStats::nonfinite_samples},
  };
  return list;
}

void RenderStats::add(const RenderStats& o) {
  // occupancy: the mean over all iterations of both, the minimum of both
  if (o.iterations > 0) {
    occupancy_min = iterations > 0 ? std::min(occupancy_min, o.occupancy_min) : o.occupancy_min;
    occupancy_mean = (occupancy_mean * double(iterations) + o.occupancy_mean * double(o.iterations)) /
                     double(iterations + o.iterations);
  }
  for (auto& [key, member] : counters()) this->*member += o.*member;
  max_throughput = std::max(max_throughput, o.max_throughput);
  for (auto& [name, t] : o.kernels) {
    kernels[name].seconds += t.seconds;
    kernels[name].launches += t.launches;
  }
}
const std::string& Renderer::device_name() const { return impl_->dev.name; }
uint32_t Renderer::features() const { return impl_->features; }
const SceneDesc& Renderer::scene() const { return impl_->scene; }

static std::vector<st_float4> to_points(const std::vector<std::array<float, 3>>& pts) {
  std::vector<st_float4> v(pts.size());
  for (size_t i = 0; i < pts.size(); ++i) v[i] = st_float4{pts[i][0], pts[i][1], pts[i][2], 0};
  return v;
}

std::vector<float> Renderer::probe_density(int medium, const std::vector<std::array<float, 3>>& world_points) {
  if (medium < 0 || medium >= impl_->st.n_media) throw Error("probe_density: no such medium");
  auto pts = to_points(world_points);
  cl::Buffer b_pts = impl_->buffer(CL_MEM_READ_ONLY, std::max<size_t>(1, pts.size()) * 16, pts.empty() ? nullptr : pts.data(), "probe points");
  return impl_->run_probe<float>("k_probe_density", pts.size(), [&](cl::Kernel& k, cl::Buffer& out) {
    k.setArg(0, impl_->b_scene);
    k.setArg(1, impl_->b_grids);
    k.setArg(2, b_pts);
    k.setArg(3, out);
    k.setArg(4, cl_int(medium));
    k.setArg(5, cl_uint(pts.size()));
  });
}

std::vector<std::array<float, 2>> Renderer::probe_majorant(int medium, const std::vector<std::array<float, 3>>& world_points) {
  if (medium < 0 || medium >= impl_->st.n_media) throw Error("probe_majorant: no such medium");
  auto pts = to_points(world_points);
  cl::Buffer b_pts = impl_->buffer(CL_MEM_READ_ONLY, std::max<size_t>(1, pts.size()) * 16, pts.empty() ? nullptr : pts.data(), "probe points");
  return impl_->run_probe<std::array<float, 2>>("k_probe_majorant", pts.size(), [&](cl::Kernel& k, cl::Buffer& out) {
    k.setArg(0, impl_->b_scene);
    k.setArg(1, impl_->b_maj);
    k.setArg(2, b_pts);
    k.setArg(3, out);
    k.setArg(4, cl_int(medium));
    k.setArg(5, cl_uint(pts.size()));
  });
}

std::vector<std::array<float, 4>> Renderer::probe_track(std::array<float, 3> o, std::array<float, 3> d, int channel, int n,
                                                        std::vector<std::array<float, 4>>* beta) {
  cl::Buffer b_beta = impl_->buffer(CL_MEM_READ_WRITE, size_t(std::max(1, n)) * 16, nullptr, "probe beta");
  auto out = impl_->run_probe<std::array<float, 4>>("k_probe_track", size_t(n), [&](cl::Kernel& k, cl::Buffer& out) {
    k.setArg(0, impl_->b_scene);
    k.setArg(1, impl_->b_grids);
    k.setArg(2, impl_->b_maj);
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
      ST_CL_CHECK(impl_->queue.enqueueReadBuffer(b_beta, CL_TRUE, 0, size_t(n) * 16, beta->data()), "read probe beta");
  }
  return out;
}

void Renderer::probe_albedo(std::array<float, 3> o, int channel, int n, std::vector<std::array<float, 4>>* scatter,
                            std::vector<std::array<float, 4>>* absorb) {
  cl::Buffer b_abs = impl_->buffer(CL_MEM_READ_WRITE, size_t(std::max(1, n)) * 16, nullptr, "probe absorption");
  *scatter = impl_->run_probe<std::array<float, 4>>("k_probe_albedo", size_t(n), [&](cl::Kernel& k, cl::Buffer& out) {
    k.setArg(0, impl_->b_scene);
    k.setArg(1, impl_->b_grids);
    k.setArg(2, impl_->b_maj);
    k.setArg(3, cl_float4{{o[0], o[1], o[2], 0}});
    k.setArg(4, cl_int(channel));
    k.setArg(5, out);
    k.setArg(6, b_abs);
    k.setArg(7, cl_uint(n));
  });
  absorb->resize(size_t(n));
  if (n > 0) ST_CL_CHECK(impl_->queue.enqueueReadBuffer(b_abs, CL_TRUE, 0, size_t(n) * 16, absorb->data()), "read probe absorption");
}

std::vector<std::array<float, 4>> Renderer::probe_phase(int type, float g, int n) {
  return impl_->run_probe<std::array<float, 4>>("k_probe_phase", size_t(n), [&](cl::Kernel& k, cl::Buffer& out) {
    k.setArg(0, impl_->b_scene);
    k.setArg(1, cl_int(type));
    k.setArg(2, cl_float(g));
    k.setArg(3, out);
    k.setArg(4, cl_uint(n));
  });
}

std::vector<std::array<float, 4>> Renderer::probe_transmittance(std::array<float, 3> o, std::array<float, 3> d, int n) {
  return impl_->run_probe<std::array<float, 4>>("k_probe_transmittance", size_t(n), [&](cl::Kernel& k, cl::Buffer& out) {
    k.setArg(0, impl_->b_scene);
    k.setArg(1, impl_->b_grids);
    k.setArg(2, impl_->b_maj);
    k.setArg(3, cl_float4{{o[0], o[1], o[2], 0}});
    k.setArg(4, cl_float4{{d[0], d[1], d[2], 0}});
    k.setArg(5, out);
    k.setArg(6, cl_uint(n));
  });
}

}  // namespace spectrack
