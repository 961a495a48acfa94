// guide_cache.cpp: the grid of cells over the media and the per-region fits (guide_cache.h): each
// region's mixture from its lit records, or pooled from the subtree or block of cells around a sparse
// region, and its selection probability learned from held-out records; the cells' kd-trees are
// guide_tree.cpp, the settings from the environment guide_settings.cpp.
#include "guiding/guide_cache.h"

#include <fmt/format.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <exception>
#include <limits>
#include <mutex>
#include <string>
#include <system_error>
#include <thread>
#include <tuple>

#include "guiding/vmf_fit.h"
#include "util/error.h"

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

size_t GuideCache::capacity_bytes() const {
  // every region refinement adds is one region and two nodes
  const size_t more = kGuideMaxRegions - std::min(regions.size(), kGuideMaxRegions);
  return bytes() + more * (sizeof(st_guide_region) + 2 * sizeof(st_guide_node));
}

std::vector<unsigned char> GuideCache::serialize() const {
  std::vector<unsigned char> out(bytes());
  st_guide_header h = header;
  h.regions = int(regions.size());
  h.nodes = int(nodes.size());
  std::memcpy(out.data(), &h, sizeof(h));
  size_t at = sizeof(h);
  auto put = [&](const void* data, size_t n) {
    if (n) std::memcpy(out.data() + at, data, n);
    at += n;
  };
  put(regions.data(), regions.size() * sizeof(st_guide_region));
  put(nodes.data(), nodes.size() * sizeof(st_guide_node));
  put(pixel_estimate.data(), pixel_estimate.size() * sizeof(float));
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
  const size_t cells = size_t(c.header.dims[0]) * c.header.dims[1] * c.header.dims[2];
  c.regions.assign(cells, st_guide_region{});
  for (size_t i = 0; i < cells; ++i) c.nodes.push_back(st_guide_node{0.0f, ST_GUIDE_LEAF | uint32_t(i)});  // leaf i: region i
  c.node_depth.assign(cells, 0);
  c.pixel_estimate.assign(size_t(std::max(st.camera.width, 0)) * size_t(std::max(st.camera.height, 0)), 0.0f);
  return c;
}

void set_pixel_estimates(GuideCache& cache, const std::vector<double>& sums, double samples) {
  double film = 0;
  for (double v : sums) film += v;
  const double floor = sums.empty() ? 0.0 : kGuidePixelFloor * film / double(sums.size()) / samples;
  for (size_t i = 0; i < sums.size() && i < cache.pixel_estimate.size(); ++i)
    cache.pixel_estimate[i] = float(std::max(sums[i] / samples, floor));
}

namespace {

using PathKey = std::tuple<uint32_t, uint32_t, uint32_t>;  // pixel, sample, channel
using PathEnds = std::vector<std::pair<PathKey, float>>;   // every path's radiance, sorted by key
using VertexKey = std::tuple<uint32_t, uint32_t, uint32_t, uint32_t>;  // pixel, sample, channel, depth
using VertexWeights = std::vector<std::pair<VertexKey, float>>;         // sorted by key

// The radiance of the path `key` from its end record, or none.
const float* path_end(const PathEnds& ends, const PathKey& key) {
  const auto e = std::lower_bound(ends.begin(), ends.end(), key,
                                  [](const std::pair<PathKey, float>& a, const PathKey& k) { return a.first < k; });
  return e != ends.end() && e->first == key ? &e->second : nullptr;
}

// The fit's weight of vertex `key` over the whole rest of its path (the full-path weights), or 0.
float full_path_weight(const VertexWeights& full, const VertexKey& key) {
  const auto e = std::lower_bound(full.begin(), full.end(), key,
                                  [](const std::pair<VertexKey, float>& a, const VertexKey& k) { return a.first < k; });
  return e != full.end() && e->first == key ? e->second : 0.0f;
}

// The fit's records of one region or of several pooled: indices into the pass's records, weights.
// With each, f_phase at its direction and the density t the training drew it with; `all` counts the
// records of weight 0 too (the directions that brought nothing back).
struct FitRecords {
  std::vector<size_t> index;
  std::vector<float> weight, phase, train;
  size_t all = 0;
  void append(const FitRecords& o) {
    index.insert(index.end(), o.index.begin(), o.index.end());
    weight.insert(weight.end(), o.weight.begin(), o.weight.end());
    phase.insert(phase.end(), o.phase.begin(), o.phase.end());
    train.insert(train.end(), o.train.begin(), o.train.end());
    all += o.all;
  }
  // Kish's effective count of the records, (sum w)^2 / sum w^2: what a fit learns from them (a
  // few bright records among many dim ones count as the few; the fit's priors count in the same
  // unit, vmf_fit.cpp)
  double effective() const {
    double sum = 0, sum2 = 0;
    for (float w : weight) sum += double(w), sum2 += double(w) * double(w);
    return sum2 > 0 ? sum * sum / sum2 : 0.0;
  }
};

// The selection probability that the records say pays (docs/guiding.md, "The learned selection
// probability"): the estimate f_phase L / p_mix of the incident light at a guided event has, under
// the one-sample mixture of selection probability a, the second moment
//     M(a) = integral of (f_phase L)^2 / p_mix = E_t[r^2 t / (a p_guide + (1 - a) f_phase)],
// with r = f_phase L / t a record drawn from t (the mean mu = E_t[r] does not depend on a). So the
// variance a removes is the mean of d = r^2 t (1 / f_phase - 1 / p_mix) over the records, records of
// weight 0 included (d = 0). Among a = 0.1, ..., kGuideAlphaMax the one that removes most wins if
// its removal stands out of the records' noise (above kGuideAlphaZ standard errors of the mean of
// d) and is at least kGuideAlphaGain of the unguided variance M(0) - mu^2; else 0, phase sampling,
// where the guide does not pay back its weights' spread. Any a < 1 keeps the estimator unbiased.
float learn_alpha(const st_vmf_mixture& mix, const std::vector<st_guide_record>& records, const FitRecords& f) {
  const double n = double(std::max(f.all, f.index.size()));
  double mean = 0, m0 = 0;
  std::vector<double> pdf(f.index.size());
  for (size_t i = 0; i < f.index.size(); ++i) {
    const st_guide_record& r = records[f.index[i]];
    const st_vec3 w = vec3_make(r.dir.x, r.dir.y, r.dir.z);
    pdf[i] = guide_pdf(&mix, w, 0.0f, w);
    mean += f.weight[i];
    m0 += double(f.weight[i]) * f.weight[i] * f.train[i] / f.phase[i];
  }
  const double v0 = m0 / n - (mean / n) * (mean / n);
  double best = 0;
  float alpha = 0;
  for (int k = 1; k <= int(kGuideAlphaMax * 10 + 0.5f); ++k) {
    const double a = 0.1 * k;
    double sum = 0, sum2 = 0;
    for (size_t i = 0; i < pdf.size(); ++i) {
      const double r = f.weight[i], p = a * pdf[i] + (1 - a) * f.phase[i];
      const double d = r * r * f.train[i] * (1 / double(f.phase[i]) - 1 / p);
      sum += d, sum2 += d * d;
    }
    const double removed = sum / n, se = std::sqrt(std::max(0.0, sum2 / n - removed * removed) / n);
    if (removed > best && removed > kGuideAlphaZ * se && removed >= kGuideAlphaGain * v0) best = removed, alpha = float(a);
  }
  return std::isfinite(best) ? alpha : 0.0f;
}

// Region g's mixture fitted to the even records of `f` (key order; at least kGuideMinRecords in
// all, at most kGuideMaxRecordsPerRegion read, every k-th beyond) where the fit is finite, its alpha
// learned from the odd ones, which the fit has not seen (a mixture fitted to records always looks
// better on them), or `fixed` where that is not negative. Returns whether it guides.
bool fit_mixture(st_guide_region& g, const std::vector<st_guide_record>& records, const FitRecords& f, float fixed) {
  FitRecords fit, held_out;
  for (size_t k = 0; k < f.index.size(); ++k) {
    FitRecords& h = k % 2 ? held_out : fit;
    h.index.push_back(f.index[k]), h.weight.push_back(f.weight[k]), h.phase.push_back(f.phase[k]);
    h.train.push_back(f.train[k]);
  }
  held_out.all = f.all / 2, fit.all = f.all - held_out.all;
  const size_t n = fit.index.size();
  const size_t stride = (n + kGuideMaxRecordsPerRegion - 1) / kGuideMaxRecordsPerRegion;
  std::vector<DirectionalSample> samples;
  double sum = 0;
  for (size_t k = 0; k < n; k += stride) {
    const st_guide_record& r = records[fit.index[k]];
    samples.push_back(DirectionalSample{{r.dir.x, r.dir.y, r.dir.z}, fit.weight[k]});
    sum += fit.weight[k];
  }
  VmfFitOptions options;
  options.max_iterations = 40;
  VmfFitResult result = fit_vmf_mixture(samples, options);
  g.mix = result.mixture;
  bool finite = true;
  for (int k = 0; k < ST_VMF_LOBES; ++k)
    finite = finite && std::isfinite(g.mix.weight[k]) && std::isfinite(g.mix.lobe[k].w);
  const float alpha = fixed < 0 ? learn_alpha(g.mix, records, held_out) : fixed;
  g.alpha = finite && sum > 0 ? alpha : 0.0f;
  g.weight = float(sum / double(samples.size()));
  return g.alpha > 0;
}

// A record's place in the canonical order: its region under the current trees (END records: -1,
// first), its key, its index in the pass's records (sort_records).
struct RecordOrder {
  int32_t region;
  uint32_t key[4];
  uint32_t index;
  bool operator<(const RecordOrder& o) const {
    return std::tie(region, key[0], key[1], key[2], key[3], index) <
           std::tie(o.region, o.key[0], o.key[1], o.key[2], o.key[3], o.index);
  }
};

// The region of records order[begin, end) (one region): its radiance from its vertices' radiance
// records joined with their paths' end records (`ends`: each path's radiance); returns the fit's
// records (positive weights, in key order, indices into `records`), weighed by the ring's credit
// or, with `full` (not empty), by the whole rest of the path; `phase` and `train` by record index.
FitRecords region_records(GuideCache& cache, const std::vector<st_guide_record>& records,
                          const std::vector<RecordOrder>& order, size_t begin, size_t end, const PathEnds& ends,
                          const VertexWeights* full, const std::vector<float>& phase, const std::vector<float>& train) {
  st_guide_region& g = cache.regions[size_t(order[begin].region)];
  double sum_radiance = 0;
  size_t n_radiance = 0;
  FitRecords f;
  for (size_t j = begin; j < end; ++j) {
    const size_t i = order[j].index;
    const st_guide_record& r = records[i];
    if (r.key[3] & ST_GUIDE_RECORD_RADIANCE) {
      const float* e = path_end(ends, PathKey{r.key[0], r.key[1], r.key[2]});
      const double L = e ? std::max(0.0, double(*e) - double(r.dir.x)) / double(r.dir.y) : 0.0;
      if (std::isfinite(L)) sum_radiance += L, ++n_radiance;
      continue;
    }
    const VertexKey key{r.key[0], r.key[1], r.key[2], r.key[3]};
    const float w = full ? full_path_weight(*full, key) : r.dir.w;
    ++f.all;
    if (!(w > 0 && std::isfinite(w))) continue;
    f.index.push_back(i), f.weight.push_back(w);
    f.phase.push_back(phase[i]), f.train.push_back(train[i]);
  }
  if (n_radiance >= size_t(kGuideMinRecords)) {
    g.records = float(n_radiance);
    g.radiance = float(sum_radiance / double(n_radiance));
  }
  return f;
}

// Sparse regions (fit records of an effective count below kGuideMinRecords: where few directions
// find light, or few bring back most of it) take the fit of the smallest set around them that
// holds enough: the subtree of their cell's kd-tree (below), then blocks of 2, 4, ... cells along
// each axis (pool_sparse_cells).
struct Pool {
  GuideCache& cache;
  const std::vector<st_guide_record>& records;
  const std::vector<FitRecords>& fit;  // per region
  std::vector<char> done;              // per region: it has its own fit or a pooled one
  float fixed_alpha;                   // fit_mixture's
  int guided = 0;

  // Fits the regions `leaves` that are not done from all their records, if there are enough.
  void pool(const std::vector<uint32_t>& leaves) {
    FitRecords all;
    bool sparse = false;
    for (uint32_t r : leaves) all.append(fit[r]), sparse = sparse || !done[r];
    if (!sparse || all.effective() < double(kGuideMinRecords)) return;
    st_guide_region pooled{};
    fit_mixture(pooled, records, all, fixed_alpha);
    for (uint32_t r : leaves) {
      if (done[r]) continue;
      st_guide_region& g = cache.regions[r];
      g.mix = pooled.mix, g.alpha = pooled.alpha, g.weight = pooled.weight;
      done[r] = 1, guided += g.alpha > 0;
    }
  }
  // The regions of node i's subtree, pooled bottom up (the smallest subtree first).
  std::vector<uint32_t> subtree(uint32_t i) {
    const st_guide_node& n = cache.nodes[i];
    if (n.next & ST_GUIDE_LEAF) return {n.next & ~ST_GUIDE_LEAF};
    std::vector<uint32_t> leaves = subtree(n.next >> 2), hi = subtree((n.next >> 2) + 1);
    leaves.insert(leaves.end(), hi.begin(), hi.end());
    pool(leaves);
    return leaves;
  }
};

// Pools sparse regions over their cells' kd-trees, then over blocks of 2^l cells per axis.
int pool_sparse_regions(GuideCache& cache, const std::vector<st_guide_record>& records, const std::vector<FitRecords>& fit,
                        std::vector<char> done, float fixed_alpha) {
  Pool p{cache, records, fit, std::move(done), fixed_alpha};
  const int* d = cache.header.dims;
  std::vector<std::vector<uint32_t>> cell(size_t(d[0]) * d[1] * d[2]);
  for (size_t c = 0; c < cell.size(); ++c) cell[c] = p.subtree(uint32_t(c));
  for (int block = 2; block / 2 < std::max({d[0], d[1], d[2]}); block *= 2)
    for (int z = 0; z < d[2]; z += block)
      for (int y = 0; y < d[1]; y += block)
        for (int x = 0; x < d[0]; x += block) {
          std::vector<uint32_t> leaves;
          for (int k = z; k < std::min(z + block, d[2]); ++k)
            for (int j = y; j < std::min(y + block, d[1]); ++j)
              for (int i = x; i < std::min(x + block, d[0]); ++i) {
                const auto& c = cell[(size_t(k) * d[1] + j) * d[0] + i];
                leaves.insert(leaves.end(), c.begin(), c.end());
              }
          p.pool(leaves);
        }
  return p.guided;
}

// Per fit record (index-aligned with `records`; radiance and end records 0), f_phase at its
// direction (the device's pos.w) and the density the training drew it with: f_phase where
// `sampled_by` did not guide there, else its one-sample mixture.
void record_densities(const std::vector<st_guide_record>& records, const GuideCache* sampled_by, std::vector<float>& phase,
                      std::vector<float>& train) {
  const bool guided = sampled_by && sampled_by->header.origin.w > 0;
  phase.assign(records.size(), 0.0f), train.assign(records.size(), 0.0f);
  for (size_t i = 0; i < records.size(); ++i) {
    const st_guide_record& r = records[i];
    if (r.key[3] & ST_GUIDE_RECORD_RADIANCE) continue;  // END records too
    double t = r.pos.w;
    if (guided) {
      const st_guide_region& g = sampled_by->regions[size_t(guide_region_of(*sampled_by, r.pos.x, r.pos.y, r.pos.z))];
      const st_vec3 w = vec3_make(r.dir.x, r.dir.y, r.dir.z);
      if (g.alpha > 0) t = guide_mixture_pdf(g.alpha, guide_pdf(&g.mix, w, 0.0f, w), r.pos.w);
    }
    phase[i] = r.pos.w, train[i] = float(t);
  }
}

// The records' canonical order: by region under the current trees, then by key. The keys are
// unique, so the order is a function of the set of records, not of the order the device appended
// them in; the records themselves stay where they are (a sort of small entries, no copy of them).
std::vector<RecordOrder> sort_records(const GuideCache& cache, const std::vector<st_guide_record>& records) {
  std::vector<RecordOrder> order(records.size());
  for (size_t i = 0; i < records.size(); ++i) {
    const st_guide_record& r = records[i];
    const int32_t region = r.key[3] == ST_GUIDE_RECORD_END ? -1 : guide_region_of(cache, r.pos.x, r.pos.y, r.pos.z);
    order[i] = RecordOrder{region, {r.key[0], r.key[1], r.key[2], r.key[3]}, uint32_t(i)};
  }
  std::sort(order.begin(), order.end());
  return order;
}

}  // namespace

int fit_guide_cache(GuideCache& cache, const std::vector<st_guide_record>& records, const GuideCache* sampled_by) {
  if (records.size() > size_t(UINT32_MAX)) throw Error(fmt::format("internal: {} guide records in one pass", records.size()));
  std::vector<float> phase, train;
  record_densities(records, sampled_by, phase, train);
  const std::vector<RecordOrder> order = sort_records(cache, records);
  PathEnds ends;  // every path's radiance (guide_radiance: the film's unit), from its one end record (region -1: first, by key)
  for (const RecordOrder& o : order)
    if (o.key[3] == ST_GUIDE_RECORD_END) ends.emplace_back(PathKey{o.key[0], o.key[1], o.key[2]}, records[o.index].dir.x);

  VertexWeights full;  // with cache.full_path: each guided vertex's weight over the rest of its path
  if (cache.full_path)
    for (const st_guide_record& r : records) {
      const uint32_t depth = r.key[3] & ~ST_GUIDE_RECORD_RADIANCE;
      if (r.key[3] == ST_GUIDE_RECORD_END || !(r.key[3] & ST_GUIDE_RECORD_RADIANCE) ||
          int64_t(depth) >= int64_t(cache.header.guided_depth))
        continue;
      const float* e = path_end(ends, PathKey{r.key[0], r.key[1], r.key[2]});
      const double w = e ? std::max(0.0, double(*e) - double(r.dir.x)) / double(r.dir.y) * double(r.dir.z) : 0.0;
      full.emplace_back(VertexKey{r.key[0], r.key[1], r.key[2], depth}, float(w));
    }
  std::sort(full.begin(), full.end());
  for (st_guide_region& g : cache.regions) g = st_guide_region{};
  std::vector<FitRecords> fit(cache.regions.size());
  for (size_t begin = 0; begin < order.size();) {
    const int32_t region = order[begin].region;
    size_t end = begin;
    while (end < order.size() && order[end].region == region) ++end;
    if (region >= 0 && size_t(region) < cache.regions.size())
      fit[size_t(region)] =
          region_records(cache, records, order, begin, end, ends, cache.full_path ? &full : nullptr, phase, train);
    begin = end;
  }
  // the learned alpha reads the mixture alone: with the phase product (its pdf per event) alpha is fixed
  const float fixed = cache.fixed_alpha >= 0 ? cache.fixed_alpha : cache.header.phase_product ? kGuideAlpha : -1.0f;
  // Each region's fit is a pure function of its records, so the regions are shared out over the
  // host's threads (the device waits for the cache meanwhile); the cache does not depend on how.
  std::vector<char> done(cache.regions.size(), 0), guides(cache.regions.size(), 0);
  std::atomic<size_t> next{0};
  std::mutex failed_mutex;
  std::exception_ptr failed;
  auto worker = [&] {
    try {
      for (size_t r; (r = next.fetch_add(1)) < fit.size();)
        if (fit[r].effective() >= double(kGuideMinRecords))
          guides[r] = char(fit_mixture(cache.regions[r], records, fit[r], fixed) != 0), done[r] = 1;
    } catch (...) {
      std::lock_guard<std::mutex> lock(failed_mutex);
      if (!failed) failed = std::current_exception();
      next = fit.size();
    }
  };
  std::vector<std::thread> threads;
  try {
    for (unsigned t = 1; t < std::clamp(std::thread::hardware_concurrency(), 1u, 16u); ++t) threads.emplace_back(worker);
  } catch (const std::system_error&) {  // no more threads: the ones started and this one share the work
  }
  worker();
  for (std::thread& t : threads) t.join();
  if (failed) std::rethrow_exception(failed);
  const int guided = int(std::count(guides.begin(), guides.end(), char(1)));
  return guided + pool_sparse_regions(cache, records, fit, std::move(done), fixed);
}

}  // namespace spectrack
