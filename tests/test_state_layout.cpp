// test_state_layout.cpp: the two layouts of the state schemas (kernels/state_schema.h: the path
// state of path_state.h and the shadow-ray entries of shadow_state.h; docs/architecture.md 'Path
// state for the GPU'):
//   - on the host, the SoA arrays of n entries tile the buffer of n * sizeof(struct) bytes in field
//     order, each aligned to its field's size, each field at its AoS offset (the shadow entries'
//     for several n = Q * NL, the transmittance estimate's fields at their place in st_shadow.tr);
//   - on the device (PoCL here), path_store and shadow_store write every field where the host's
//     layout says, in both layouts, and a group-wise store writes its group's fields and nothing
//     else; twin: the AoS buffer read as SoA does not match, so the check can fail;
//   - renders with SPECTRACK_STATE_LAYOUT=aos and =soa give bit-identical films and counters (rgb
//     with every stage, and spectral mode with film layers, which load the path's wavelengths and
//     vertex in the tracking kernel; and both modes with shadow rays through ray marching, resumed
//     by a small budget, and equi-angular entries towards a point and a spot light); twin: another
//     seed changes the film, so the comparison can fail; a layout that is neither is refused by name.
#include <cstring>
#include <type_traits>

#include "cli_util.h"
#include "device/opencl.h"
#include "kernels/types.h"

namespace {

using namespace st_cli;

struct FieldInfo {
  const char* name;
  size_t size, aos_offset, soa_offset;
  int group;
  bool is_float;  // float or st_float4 (else st_uint, st_int)
};

// A schema's fields, in list order, and its struct's size.
struct Schema {
  const char* name;
  std::vector<FieldInfo> fields;
  size_t entry_bytes;
  int all_groups;
};

template <typename T>
constexpr bool kIsFloat = std::is_same<T, float>::value || std::is_same<T, st_float4>::value;

Schema path_schema() {
  Schema s{"path", {}, sizeof(st_path), ST_PATH_ALL};
#define ST_X_FIELD_INFO(S, type, name, group)                                                            \
  s.fields.push_back({#name, sizeof(type), offsetof(st_path, name), st_path_field_offset(ST_PATH_F_##name), \
                      ST_PATH_##group, kIsFloat<type>});
  ST_PATH_FIELDS(ST_X_FIELD_INFO)
#undef ST_X_FIELD_INFO
  return s;
}

// The shadow entry's fields: the transmittance estimate's at their place in st_shadow.tr.
Schema shadow_schema() {
  Schema s{"shadow", {}, sizeof(st_shadow), ST_SHADOW_ALL};
#define ST_X_FIELD_INFO_AT(type, name, group, aos)                                                  \
  s.fields.push_back({#name, sizeof(type), aos, st_shadow_field_offset(ST_SHADOW_F_##name), ST_SHADOW_##group, \
                      kIsFloat<type>});
#define ST_X_FIELD_INFO(S, type, name, group) ST_X_FIELD_INFO_AT(type, name, group, offsetof(st_shadow, name))
#define ST_X_TRANS_INFO(S, type, name, group) \
  ST_X_FIELD_INFO_AT(type, name, group, offsetof(st_shadow, tr) + offsetof(st_trans, name))
  ST_SHADOW_HEAD_FIELDS(ST_X_FIELD_INFO)
  ST_TRANS_FIELDS(ST_X_TRANS_INFO)
  ST_SHADOW_TAIL_FIELDS(ST_X_FIELD_INFO)
#undef ST_X_FIELD_INFO
#undef ST_X_TRANS_INFO
#undef ST_X_FIELD_INFO_AT
  return s;
}

// The SoA arrays of n entries tile the buffer of n entries, in field order, each aligned.
void expect_soa_tiles(const Schema& s, size_t n) {
  size_t end = 0;
  for (const FieldInfo& x : s.fields) {
    EXPECT_EQ(x.soa_offset, x.aos_offset) << s.name << "." << x.name;
    EXPECT_EQ(n * x.soa_offset, end) << s.name << "." << x.name << " n " << n;  // right after the previous array
    EXPECT_EQ((n * x.soa_offset) % x.size, 0u) << s.name << "." << x.name << " n " << n;
    end = n * x.soa_offset + n * x.size;
  }
  EXPECT_EQ(end, n * s.entry_bytes) << "the SoA arrays fill the AoS buffer exactly: " << s.name << ", n " << n;
  int groups = 0;
  for (const FieldInfo& x : s.fields) groups |= x.group;
  EXPECT_EQ(groups, s.all_groups) << s.name;  // every group holds a field
}

TEST(StateLayout, SoaArraysTileThePathBuffer) {
  const Schema s = path_schema();
  ASSERT_EQ(s.fields.size(), size_t(ST_PATH_FIELD_COUNT));
  for (size_t Q : {size_t(1), size_t(3), size_t(37), size_t(1) << 20}) expect_soa_tiles(s, Q);
}

TEST(StateLayout, SoaArraysTileTheShadowBuffer) {
  const Schema s = shadow_schema();
  ASSERT_EQ(s.fields.size(), size_t(ST_SHADOW_FIELD_COUNT));
  EXPECT_EQ(s.entry_bytes, 272u);
  // n = Q * NL: NL = entries per bounce (lights, and an equi-angular entry) times the shadow ring
  for (size_t Q : {size_t(1), size_t(37), size_t(1) << 16})
    for (size_t NL : {size_t(1), size_t(2 * 3), size_t(9 * ST_MAX_SHADOW_RING)}) expect_soa_tiles(s, Q * NL);
  // the transmittance estimate's fields lie inside st_shadow.tr, T first
  EXPECT_EQ(st_shadow_field_offset(ST_SHADOW_F_T), offsetof(st_shadow, tr));
  EXPECT_EQ(st_shadow_field_offset(ST_SHADOW_F_pad0) + 4, offsetof(st_shadow, tr) + sizeof(st_trans));
}

// Every field of entry i gets the value i * 64 + (its field index), each lane of a float4 too.
const char* kStoreProbe = R"CL(
#define ST_X_FILL(S, type, name, group) p.name = (type)((float)(i * 64u + (uint)ST_##S##_F_##name));
#define ST_X_FILL_TRANS(S, type, name, group) p.tr.name = (type)((float)(i * 64u + (uint)ST_##S##_F_##name));
__kernel void k_path_store(ST_PATH_STATE state, uint n, uint groups) {
  const uint i = get_global_id(0);
  if (i >= n) return;
  st_path p;
  ST_PATH_FIELDS(ST_X_FILL)
  path_store(state, n, i, groups, &p);
}
__kernel void k_shadow_store(ST_SHADOW_STATE state, uint n, uint groups) {
  const uint i = get_global_id(0);
  if (i >= n) return;
  st_shadow p;
  ST_SHADOW_HEAD_FIELDS(ST_X_FILL)
  ST_TRANS_FIELDS(ST_X_FILL_TRANS)
  ST_SHADOW_TAIL_FIELDS(ST_X_FILL)
  shadow_store(state, n, i, groups, &p);
}
)CL";

// The words of a buffer of n entries of schema s written by its store (k_<s>_store(groups)) in a
// layout (1: SoA), the buffer filled with 0xff bytes before.
std::vector<uint32_t> device_store(const Schema& s, bool soa, uint32_t n, uint32_t groups) {
  using namespace spectrack;
  DeviceInfo dev = select_device("");
  cl::Context ctx(dev.device);
  const std::string src = std::string(soa ? "#define ST_STATE_SOA 1\n" : "") + kernel_files_source({"types.h"}) + kStoreProbe;
  ProgramBuild pb = build_program(ctx, dev, src, "-cl-std=CL1.2", true);
  cl::CommandQueue q(ctx, dev.device);
  std::vector<uint32_t> words(n * s.entry_bytes / 4, 0xffffffffu);
  cl::Buffer b(ctx, CL_MEM_READ_WRITE | CL_MEM_COPY_HOST_PTR, words.size() * 4, words.data());
  cl::Kernel k(pb.program, (std::string("k_") + s.name + "_store").c_str());
  k.setArg(0, b);
  k.setArg(1, n);
  k.setArg(2, groups);
  q.enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange(n));
  q.enqueueReadBuffer(b, CL_TRUE, 0, words.size() * 4, words.data());
  return words;
}

// Mismatches between a buffer and what the store of `groups` should have written, read in a layout.
int layout_mismatches(const Schema& s, const std::vector<uint32_t>& words, bool soa, uint32_t n, uint32_t groups) {
  int bad = 0, index = 0;
  for (const FieldInfo& x : s.fields) {
    for (uint32_t i = 0; i < n; ++i) {
      const size_t byte = soa ? n * x.soa_offset + i * x.size : i * s.entry_bytes + x.aos_offset;
      for (size_t w = 0; w < x.size / 4; ++w) {
        const uint32_t got = words[byte / 4 + w];
        const float v = float(i * 64u + uint32_t(index));
        uint32_t want = 0xffffffffu;
        if (groups & uint32_t(x.group)) {
          if (x.is_float) std::memcpy(&want, &v, 4);  // a float, a float4's lanes
          else want = uint32_t(i * 64u + uint32_t(index));  // st_uint, st_int
        }
        bad += got != want;
      }
    }
    ++index;
  }
  return bad;
}

// Every field stored where the host's layout says, group by group; twin: the other layout's reading
// does not match.
void expect_device_layout(const Schema& s, uint32_t n, const std::vector<uint32_t>& group_sets) {
  const uint32_t all = uint32_t(s.all_groups);
  for (bool soa : {false, true}) {
    const char* layout = soa ? "soa" : "aos";
    const std::vector<uint32_t> words = device_store(s, soa, n, all);
    EXPECT_EQ(layout_mismatches(s, words, soa, n, all), 0) << s.name << " " << layout;
    for (uint32_t g : group_sets)
      EXPECT_EQ(layout_mismatches(s, device_store(s, soa, n, g), soa, n, g), 0) << s.name << " " << layout << " groups " << g;
    EXPECT_GT(layout_mismatches(s, words, !soa, n, all), 0) << s.name << " " << layout;
  }
}

TEST(StateLayout, DeviceStoresWhereTheHostLayoutSays) {
  expect_device_layout(path_schema(), 37, {ST_PATH_TRACK, ST_PATH_KEY | ST_PATH_SPECTRUM, ST_PATH_RADIANCE | ST_PATH_VERTEX});
}

TEST(StateLayout, DeviceStoresShadowEntriesWhereTheHostLayoutSays) {
  // n = Q * NL = 7 * 6; the groups k_shadow writes, the estimate's two groups apart, the cold ones
  expect_device_layout(shadow_schema(), 7 * 6,
                       {ST_SHADOW_RAY | ST_SHADOW_T | ST_SHADOW_KEY, ST_SHADOW_MARCH, ST_SHADOW_WEIGHT | ST_SHADOW_EA | ST_SHADOW_STATUS,
                        ST_SHADOW_LS | ST_SHADOW_SEGMENT});
}

// The lumpy sky scene on a small film; with `local_lights`, also a point light in the volume and a
// spot light onto it, equi-angular sampling on and ray-marching transmittance: shadow rays through
// ray marching and equi-angular entries (both legs).
json layout_scene(const std::string& dir, bool local_lights) {
  const std::string vdb = dir + "/lumpy.vdb";
  if (!fs::exists(vdb)) st_test::write_lumpy(vdb);
  json scene = lumpy_sky_scene(vdb);
  scene["film"]["width"] = 20;
  scene["film"]["height"] = 16;
  if (local_lights) {
    scene["lights"].push_back({{"type", "point"}, {"position", {0.1, 0.2, 0.0}}, {"intensity", {2.0, 1.5, 1.0}}});
    scene["lights"].push_back({{"type", "spot"}, {"position", {-1.5, 2.0, -1.0}}, {"look_at", {0, 0, 0}},
                               {"intensity", {8, 8, 6}}, {"cone_angle_deg", 25}, {"cone_delta_deg", 5}});
    scene["render"]["equiangular"] = "on";
    scene["render"]["transmittance"] = "ray-marching";
  }
  return scene;
}

// A render of `scene` under `env` (`env NAME=VALUE spectrack render ...`): its film and statistics.
struct LayoutRender {
  std::vector<float> pixels;
  json stats;
};

LayoutRender render(const std::string& dir, const json& scene, const std::string& tag, const std::string& layout,
                    const std::vector<std::string>& extra) {
  const std::string path = write_scene(dir, tag + "_scene.json", scene);
  std::vector<std::string> args = {"SPECTRACK_STATE_LAYOUT=" + layout, SPECTRACK_BINARY, "render", path, "--spp", "6",
                                   "--path-slots", "700", "-o", dir + "/" + tag + ".exr", "--stats-json",
                                   dir + "/" + tag + ".json", "--quiet"};
  args.insert(args.end(), extra.begin(), extra.end());
  RunOptions o;
  o.timeout_s = 600;
  o.binary = "/usr/bin/env";
  const Proc p = run(args, o);
  EXPECT_TRUE(p.exited && p.code == 0) << p.describe();
  return {image_pixels(dir + "/" + tag + ".exr"), json::parse(std::ifstream(dir + "/" + tag + ".json"))};
}

// Films and counters of both layouts agree on each case (scene, arguments); twin: another seed
// changes the film, so the comparison can fail.
void expect_layouts_agree(const std::string& dir, const std::vector<std::pair<json, std::vector<std::string>>>& cases) {
  for (size_t c = 0; c < cases.size(); ++c) {
    const std::string tag = "case" + std::to_string(c);
    const json& scene = cases[c].first;
    const LayoutRender aos = render(dir, scene, tag + "_aos", "aos", cases[c].second);
    const LayoutRender soa = render(dir, scene, tag + "_soa", "soa", cases[c].second);
    ASSERT_FALSE(aos.pixels.empty());
    EXPECT_EQ(aos.stats["state_layout"], "aos");
    EXPECT_EQ(soa.stats["state_layout"], "soa");
    EXPECT_EQ(aos.pixels, soa.pixels) << tag;
    for (const char* k : {"paths", "density_lookups", "density_lookups_shadow", "real_collisions", "null_collisions",
                          "scatter_events", "requeues", "iterations"})
      EXPECT_EQ(aos.stats[k], soa.stats[k]) << tag << " " << k;
    std::vector<std::string> seeded = cases[c].second;
    seeded.insert(seeded.end(), {"--seed", "8"});  // the scene's is 7
    const LayoutRender other = render(dir, scene, tag + "_seed", "soa", seeded);
    EXPECT_NE(other.pixels, soa.pixels) << tag;
  }
}

TEST(StateLayout, AosAndSoaRenderTheSameFilm) {
  const std::string dir = test_dir();
  const json sky = layout_scene(dir, false);
  expect_layouts_agree(dir, {{sky, {}}, {sky, {"--spectral", "--aov", "emission,direct,depth"}}});
}

// Shadow entries in both layouts: ray marching's fields, resumed estimates (a budget of 4 steps per
// launch), equi-angular entries' segments and both legs, in rgb and spectral mode.
TEST(StateLayout, AosAndSoaRenderTheSameFilmWithMarchingAndEquiangularShadowRays) {
  const std::string dir = test_dir();
  const json lit = layout_scene(dir, true);
  expect_layouts_agree(dir, {{lit, {"--budget", "4"}}, {lit, {"--spectral", "--budget", "4", "--aov", "direct"}}});
}

TEST(StateLayout, AnUnknownLayoutIsRefusedByName) {
  const std::string dir = test_dir();
  const std::string path = write_scene(dir, "scene.json", small_noise_scene(dir));
  RunOptions o;
  o.binary = "/usr/bin/env";
  Proc p = run({"SPECTRACK_STATE_LAYOUT=columns", SPECTRACK_BINARY, "render", path, "--spp", "1", "-o", dir + "/x.exr", "--quiet"}, o);
  EXPECT_TRUE(p.exited && p.code != 0) << p.describe();
  EXPECT_THAT(p.out, testing::HasSubstr("SPECTRACK_STATE_LAYOUT: 'columns' is not a path state layout"));
}

}  // namespace
