// test_guiding_tree.cpp: the guide cache's regions refined by record counts (guide_cache.h,
// guide_tree.cpp):
//   - a cell holding a crowded cluster and a sparse background of radiance records splits until
//     every region holds at most the threshold, each split leaving both halves at least half of
//     their parent's records (median splits), with more regions where the records crowd;
//   - the memory bound stops refinement at exactly that many regions, most crowded first;
//   - the tree depends on the set of records, not on their order (shuffled: the same nodes, bit for
//     bit), and records that are not radiance records (the fit's, the paths' ends) do not count;
//   - the fit bins records into the refined regions (each region's radiance from its own records);
//   - the device's region lookup agrees with the host's binning on every position (PoCL here).
#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>
#include <random>
#include <set>

#include "device/opencl.h"
#include "guiding/guide_cache.h"
#include "test_util.h"

using namespace spectrack;

namespace {

st_guide_record radiance_record(float x, float y, float z, uint32_t pixel) {
  st_guide_record r{};
  r.pos = st_float4{x, y, z, 0.0f};
  r.dir = st_float4{0.0f, 1.0f, 0.0f, 0.0f};  // total 0, throughput 1
  r.key[0] = pixel, r.key[1] = 0, r.key[2] = 0, r.key[3] = 1u | ST_GUIDE_RECORD_RADIANCE;
  return r;
}

// 3000 radiance records in the corner [0, 0.1]^3 of the unit box, 1000 over the whole box, and as
// many records that must not count: a fit record at every cluster point, an end record per path.
std::vector<st_guide_record> clustered_records() {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  std::vector<st_guide_record> out;
  for (uint32_t i = 0; i < 4000; ++i) {
    const float s = i < 3000 ? 0.1f : 1.0f;
    out.push_back(radiance_record(s * u(rng), s * u(rng), s * u(rng), i));
    st_guide_record end{};
    end.dir.x = 1.0f;
    end.key[0] = i, end.key[3] = ST_GUIDE_RECORD_END;
    out.push_back(end);
    if (i < 3000) {
      st_guide_record fit = out[out.size() - 2];
      fit.key[3] = 0u, fit.dir = st_float4{0.0f, 0.0f, 1.0f, 1.0f};
      out.push_back(fit);
    }
  }
  return out;
}

GuideCache unit_cache() {
  st_scene st{};  // no media: the unit box
  st.camera.width = 4;
  st.camera.height = 4;
  return make_guide_cache(st, 1);
}

// Radiance records per region under the cache's trees.
std::map<int, int> counts(const GuideCache& c, const std::vector<st_guide_record>& records) {
  std::map<int, int> n;
  for (const st_guide_record& r : records)
    if (r.key[3] != ST_GUIDE_RECORD_END && (r.key[3] & ST_GUIDE_RECORD_RADIANCE)) ++n[guide_region_of(c, r.pos.x, r.pos.y, r.pos.z)];
  return n;
}

}  // namespace

TEST(GuidingTree, SplitsCrowdedRegionsAtTheirMedianWithinTheThreshold) {
  GuideCache c = unit_cache();
  ASSERT_EQ(c.regions.size(), 1u);
  const std::vector<st_guide_record> records = clustered_records();
  const size_t added = refine_guide_regions(c, records, 256, kGuideMaxRegions);
  EXPECT_EQ(c.regions.size(), 1 + added);
  EXPECT_EQ(c.nodes.size(), 1 + 2 * added);
  const std::map<int, int> n = counts(c, records);
  EXPECT_EQ(n.size(), c.regions.size()) << "every region holds records";
  for (const auto& [region, k] : n) {
    EXPECT_LE(k, 256) << "region " << region;
    EXPECT_GE(k, 128) << "region " << region << ": a median split leaves each half at least half";
  }
  EXPECT_EQ(added + 1, 16u) << "4000 records: 16 regions of 250";
  std::set<int> in_cluster, outside;
  for (const st_guide_record& r : records) {
    if (!(r.key[3] & ST_GUIDE_RECORD_RADIANCE) || r.key[3] == ST_GUIDE_RECORD_END) continue;
    (r.key[0] < 3000 ? in_cluster : outside).insert(guide_region_of(c, r.pos.x, r.pos.y, r.pos.z));
  }
  EXPECT_GE(in_cluster.size(), 11u) << "the crowded corner gets the regions";
  EXPECT_GT(c.header.depth, 3);
  const std::vector<unsigned char> bytes = c.serialize();
  st_guide_header h;
  std::memcpy(&h, bytes.data(), sizeof h);
  EXPECT_EQ(h.regions, int(c.regions.size()));
  EXPECT_EQ(h.nodes, int(c.nodes.size()));
  EXPECT_EQ(bytes.size(), c.bytes());
  EXPECT_GE(c.capacity_bytes(), c.bytes() + (kGuideMaxRegions - c.regions.size()) * sizeof(st_guide_region));
}

TEST(GuidingTree, StopsAtTheMemoryBoundAndIgnoresTheRecordsOrder) {
  const std::vector<st_guide_record> records = clustered_records();
  GuideCache bounded = unit_cache();
  refine_guide_regions(bounded, records, 256, 7);
  EXPECT_EQ(bounded.regions.size(), 7u);
  GuideCache a = unit_cache(), b = unit_cache();
  refine_guide_regions(a, records, 100, kGuideMaxRegions);
  std::vector<st_guide_record> shuffled = records;
  std::shuffle(shuffled.begin(), shuffled.end(), std::mt19937(11));
  refine_guide_regions(b, shuffled, 100, kGuideMaxRegions);
  ASSERT_EQ(a.nodes.size(), b.nodes.size());
  EXPECT_EQ(std::memcmp(a.nodes.data(), b.nodes.data(), a.nodes.size() * sizeof(st_guide_node)), 0) << "same records, same tree";
  GuideCache fewer = unit_cache();
  shuffled.resize(shuffled.size() - 10);  // the twin: another set of records gives another tree
  refine_guide_regions(fewer, shuffled, 100, kGuideMaxRegions);
  EXPECT_TRUE(fewer.nodes.size() != a.nodes.size() ||
              std::memcmp(a.nodes.data(), fewer.nodes.data(), a.nodes.size() * sizeof(st_guide_node)) != 0);
}

TEST(GuidingTree, TheFitBinsRecordsIntoTheRefinedRegions) {
  GuideCache c = unit_cache();
  std::vector<st_guide_record> records;
  for (uint32_t i = 0; i < 200; ++i) {  // two halves of the box: radiance 1 below x = 0.5, 4 above
    const float x = (float(i) + 0.5f) / 200.0f;
    records.push_back(radiance_record(x, 0.5f, 0.5f, i));
    st_guide_record end{};
    end.dir.x = x < 0.5f ? 1.0f : 4.0f;
    end.key[0] = i, end.key[3] = ST_GUIDE_RECORD_END;
    records.push_back(end);
  }
  refine_guide_regions(c, records, 60, kGuideMaxRegions);
  fit_guide_cache(c, records);
  ASSERT_GE(c.regions.size(), 2u);
  const st_guide_region& lo = c.regions[size_t(guide_region_of(c, 0.1f, 0.5f, 0.5f))];
  const st_guide_region& hi = c.regions[size_t(guide_region_of(c, 0.9f, 0.5f, 0.5f))];
  EXPECT_FLOAT_EQ(lo.radiance, 1.0f);
  EXPECT_FLOAT_EQ(hi.radiance, 4.0f);
}

namespace {

const char* kRegionProbe = R"CL(
__kernel void k_region_probe(__global const st_guide_header* h, __global const float4* pts, uint n, __global int* out) {
  uint i = get_global_id(0);
  if (i < n) out[i] = guide_region_index(h, pts[i].x, pts[i].y, pts[i].z);
}
)CL";

}  // namespace

// The device's lookup (kernels/guiding.h guide_region_index) and the host's binning agree on every
// position: the records' own (the splits are some of them), random ones, and ones outside the grid.
// The twin: a tree with one split moved by one float step disagrees.
TEST(GuidingTree, DeviceLookupMatchesTheHost) {
  st_scene st{};
  st.camera.width = 4;
  st.camera.height = 4;
  GuideCache c = make_guide_cache(st, 2);
  const std::vector<st_guide_record> records = clustered_records();
  refine_guide_regions(c, records, 100, kGuideMaxRegions);
  ASSERT_GT(c.regions.size(), 30u);
  std::vector<cl_float4> pts;
  for (const st_guide_record& r : records) pts.push_back({{r.pos.x, r.pos.y, r.pos.z, 0.0f}});
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-0.2f, 1.2f);
  for (int i = 0; i < 20000; ++i) pts.push_back({{u(rng), u(rng), u(rng), 0.0f}});
  const cl_uint n = cl_uint(pts.size());
  DeviceInfo dev = select_device("");
  cl::Context ctx(dev.device);
  const std::string src = "#pragma OPENCL FP_CONTRACT OFF\n" + kernel_files_source({"guiding.h"}) + kRegionProbe;
  ProgramBuild pb = build_program(ctx, dev, src, "-cl-std=CL1.2", true);
  cl::CommandQueue q(ctx, dev.device);
  std::vector<unsigned char> g = c.serialize();
  cl::Buffer bg(ctx, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, g.size(), g.data());
  cl::Buffer bp(ctx, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, pts.size() * sizeof(cl_float4), pts.data());
  cl::Buffer bo(ctx, CL_MEM_WRITE_ONLY, n * sizeof(cl_int));
  cl::Kernel k(pb.program, "k_region_probe");
  k.setArg(0, bg), k.setArg(1, bp), k.setArg(2, n), k.setArg(3, bo);
  q.enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange(n));
  std::vector<cl_int> device(n);
  q.enqueueReadBuffer(bo, CL_TRUE, 0, n * sizeof(cl_int), device.data());
  GuideCache moved = c;
  for (st_guide_node& node : moved.nodes)
    if (!(node.next & ST_GUIDE_LEAF)) {
      node.split = std::nextafter(node.split, 2.0f);  // the median record now falls below it
      break;
    }
  size_t differ = 0, differ_moved = 0;
  for (cl_uint i = 0; i < n; ++i) {
    const float* p = pts[i].s;
    differ += device[i] != guide_region_of(c, p[0], p[1], p[2]);
    differ_moved += device[i] != guide_region_of(moved, p[0], p[1], p[2]);
  }
  EXPECT_EQ(differ, 0u) << "of " << n << " positions";
  EXPECT_GT(differ_moved, 0u) << "the twin: a split moved by one float step must be seen";
}
