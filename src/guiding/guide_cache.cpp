// guide_cache.cpp: the grid of regions over the media and the per-region fits (guide_cache.h).
#include "guiding/guide_cache.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <tuple>

#include "guiding/vmf_fit.h"

namespace spectrack {

namespace {

// The world box of a medium: its majorant grid's index box through the inverse of world_to_index.
void medium_world_box(const st_medium& m, double lo[3], double hi[3]) {
  double A[3][3], b[3];
  for (int r = 0; r < 3; ++r) {
    const st_float4& row = m.world_to_index[r];
    A[r][0] = row.x, A[r][1] = row.y, A[r][2] = row.z, b[r] = row.w;
  }
  const double det = A[0][0] * (A[1][1] * A[2][2] - A[1][2] * A[2][1]) - A[0][1] * (A[1][0] * A[2][2] - A[1][2] * A[2][0]) +
                     A[0][2] * (A[1][0] * A[2][1] - A[1][1] * A[2][0]);
  double inv[3][3];
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) {  // the adjugate's (r, c): the cofactor of (c, r)
      const int r1 = (c + 1) % 3, r2 = (c + 2) % 3, c1 = (r + 1) % 3, c2 = (r + 2) % 3;
      inv[r][c] = (A[r1][c1] * A[r2][c2] - A[r1][c2] * A[r2][c1]) / det;
    }
  const double cell = m.maj_origin.w, o[3] = {m.maj_origin.x, m.maj_origin.y, m.maj_origin.z};
  for (int a = 0; a < 3; ++a) lo[a] = INFINITY, hi[a] = -INFINITY;
  for (int corner = 0; corner < 8; ++corner) {
    double idx[3];
    for (int a = 0; a < 3; ++a) idx[a] = o[a] + ((corner >> a) & 1 ? m.maj_dims[a] * cell : 0.0) - b[a];
    for (int r = 0; r < 3; ++r) {
      const double w = inv[r][0] * idx[0] + inv[r][1] * idx[1] + inv[r][2] * idx[2];
      lo[r] = std::min(lo[r], w), hi[r] = std::max(hi[r], w);
    }
  }
}

}  // namespace

std::vector<unsigned char> GuideCache::serialize() const {
  std::vector<unsigned char> out(bytes());
  std::memcpy(out.data(), &header, sizeof(header));
  if (!regions.empty()) std::memcpy(out.data() + sizeof(header), regions.data(), regions.size() * sizeof(st_guide_region));
  return out;
}

GuideCache make_guide_cache(const st_scene& st, int cells_longest_axis) {
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (int i = 0; i < st.n_media; ++i) {
    double l[3], h[3];
    medium_world_box(st.media[i], l, h);
    for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], l[a]), hi[a] = std::max(hi[a], h[a]);
  }
  GuideCache c;
  double ext[3], longest = 0;
  for (int a = 0; a < 3; ++a) {
    if (!(hi[a] > lo[a]) || !std::isfinite(hi[a] - lo[a])) lo[a] = 0, hi[a] = 1;  // no media: one cell
    ext[a] = hi[a] - lo[a];
    longest = std::max(longest, ext[a]);
  }
  const float origin[3] = {float(lo[0]), float(lo[1]), float(lo[2])};
  float inv_cell[3];
  for (int a = 0; a < 3; ++a) {
    c.header.dims[a] = std::max(1, int(std::ceil(cells_longest_axis * ext[a] / longest - 1e-6)));
    inv_cell[a] = float(c.header.dims[a] / ext[a]);
  }
  c.header.origin = st_float4{origin[0], origin[1], origin[2], 0.0f};
  c.header.inv_cell = st_float4{inv_cell[0], inv_cell[1], inv_cell[2], 0.0f};
  c.header.guided_depth = kGuideDepth;
  c.regions.assign(size_t(c.header.dims[0]) * c.header.dims[1] * c.header.dims[2], st_guide_region{});
  return c;
}

int fit_guide_cache(GuideCache& cache, std::vector<st_guide_record> records) {
  auto region_of = [](const st_guide_record& r) {
    int32_t i;
    std::memcpy(&i, &r.pos.w, 4);
    return i;
  };
  auto order = [&](const st_guide_record& a, const st_guide_record& b) {
    return std::make_tuple(region_of(a), a.key[0], a.key[1], a.key[2], a.key[3]) <
           std::make_tuple(region_of(b), b.key[0], b.key[1], b.key[2], b.key[3]);
  };
  std::sort(records.begin(), records.end(), order);
  for (st_guide_region& g : cache.regions) g = st_guide_region{};
  int guided = 0;
  VmfFitOptions options;
  options.max_iterations = 40;
  for (size_t begin = 0; begin < records.size();) {
    const int region = region_of(records[begin]);
    size_t end = begin;
    while (end < records.size() && region_of(records[end]) == region) ++end;
    const size_t n = end - begin;
    if (region >= 0 && size_t(region) < cache.regions.size() && n >= size_t(kGuideMinRecords)) {
      const size_t stride = (n + kGuideMaxRecordsPerRegion - 1) / kGuideMaxRecordsPerRegion;
      std::vector<DirectionalSample> samples;
      double sum = 0;
      for (size_t i = begin; i < end; i += stride) {
        const st_guide_record& r = records[i];
        samples.push_back(DirectionalSample{{r.dir.x, r.dir.y, r.dir.z}, r.dir.w});
        sum += r.dir.w;
      }
      VmfFitResult fit = fit_vmf_mixture(samples, options);
      st_guide_region& g = cache.regions[size_t(region)];
      g.mix = fit.mixture;
      bool finite = true;
      for (int k = 0; k < ST_VMF_LOBES; ++k)
        finite = finite && std::isfinite(g.mix.weight[k]) && std::isfinite(g.mix.lobe[k].w);
      g.alpha = finite && sum > 0 ? kGuideAlpha : 0.0f;
      g.records = float(samples.size());
      g.radiance = float(sum / double(samples.size()));
      guided += g.alpha > 0;
    }
    begin = end;
  }
  return guided;
}

}  // namespace spectrack
