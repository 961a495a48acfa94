// test_wavefront.cpp: the stage loop on the device (docs/architecture.md, 'The stage loop on the
// device'): a render in chunks of iterations (a GPU's loop) waits for the device at most once per
// 8 iterations (host_waits in the stats), the schedule changes no pixel (one iteration per read,
// the queue trace, and the sized loop against chunks of iterations; one
// work-group per stage launch, whose work-items then take many items each, in runs or strided,
// against the default launch size), and every statistic the device folds matches the lockstep
// render's. The loop policy (src/integrator/loop_policy.h) by device type: chunked over 2048
// strided work-items per compute unit on a GPU; on a CPU device two work-groups per core taking
// runs of items from the queues' tickets; the overrides, and values refused by name. The twins: the lockstep render's own host_waits, one per iteration, must fail the 1/8
// bound, so the bound can fail; and another seed must change the image, so the comparison can.
#include "cli_util.h"
#include "integrator/loop_policy.h"
#include "util/error.h"

namespace {

using namespace st_cli;

struct ScopedEnv {
  std::string name;
  ScopedEnv(const char* n, const char* v) : name(n) { ::setenv(n, v, 1); }
  ~ScopedEnv() { ::unsetenv(name.c_str()); }
};

struct Render {
  std::vector<float> pixels;
  json stats;
};

// The lumpy chromatic volume under a sky and a sun (every stage runs), 24x24, several batches.
Render render(const std::string& dir, const std::string& tag, const std::vector<std::string>& extra = {}) {
  const std::string vdb = dir + "/lumpy.vdb";
  if (!fs::exists(vdb)) st_test::write_lumpy(vdb);
  json scene = lumpy_sky_scene(vdb);
  scene["film"]["width"] = 24;
  scene["film"]["height"] = 24;
  const std::string path = write_scene(dir, tag + ".json", scene);
  std::vector<std::string> args = {"render", path, "--spp", "32", "--path-slots", "1024", "--batches-in-flight", "2",
                                   "-o", dir + "/" + tag + ".exr", "--stats-json", dir + "/" + tag + ".stats.json", "--quiet"};
  args.insert(args.end(), extra.begin(), extra.end());
  RunOptions o;
  o.timeout_s = 600;
  Proc p = run(args, o);
  EXPECT_TRUE(p.exited && p.code == 0) << p.describe();
  Render r;
  r.pixels = image_pixels(dir + "/" + tag + ".exr");
  r.stats = json::parse(std::ifstream(dir + "/" + tag + ".stats.json"));
  return r;
}

double waits_per_iteration(const json& s) {
  return s["host_waits"].get<double>() / std::max(1.0, s["iterations"].get<double>());
}

TEST(Wavefront, ChunksOfIterationsWaitRarelyAndChangeNoPixel) {
  const std::string dir = test_dir();
  Render chunked, lockstep, sized;
  {
    ScopedEnv loop("SPECTRACK_LOOP", "chunked");  // the GPU's loop, on any device
    chunked = render(dir, "chunked");
    ScopedEnv trace("SPECTRACK_TRACE_QUEUES", "1");  // one iteration per read
    lockstep = render(dir, "lockstep");
  }
  {
    ScopedEnv loop("SPECTRACK_LOOP", "sized");  // one read per iteration, launches sized by it
    sized = render(dir, "sized");
  }
  ASSERT_FALSE(chunked.pixels.empty());
  EXPECT_EQ(chunked.pixels, lockstep.pixels);
  EXPECT_EQ(chunked.pixels, sized.pixels);
  EXPECT_EQ(chunked.stats["density_lookups"], sized.stats["density_lookups"]);
  ASSERT_GE(chunked.stats["iterations"].get<int>(), 64) << "too few iterations to measure waits";
  EXPECT_LE(waits_per_iteration(chunked.stats), 1.0 / 8.0) << chunked.stats.dump();
  // twin: the lockstep loop waits once per iteration, which the bound refuses
  EXPECT_GT(waits_per_iteration(lockstep.stats), 1.0 / 8.0) << lockstep.stats.dump();
  EXPECT_GE(lockstep.stats["host_waits"].get<int>(), lockstep.stats["iterations"].get<int>());
  // the device's sums and occupancy are the same whatever the host's reads
  for (const char* k : {"iterations", "paths", "density_lookups", "real_collisions", "null_collisions", "dda_steps",
                        "scatter_events", "waiting_requeues", "iterations_below_half_occupancy", "occupancy_mean",
                        "occupancy_min", "max_throughput"})
    EXPECT_EQ(chunked.stats[k], lockstep.stats[k]) << k;
  EXPECT_EQ(chunked.stats["paths"].get<int>(), 24 * 24 * 32);
}

TEST(Wavefront, StridingWorkItemsChangeNoPixel) {
  const std::string dir = test_dir();
  Render wide, narrow, strided, grabbed, blocked;
  {
    ScopedEnv loop("SPECTRACK_LOOP", "chunked");  // launches of a fixed size, whatever the queue's
    wide = render(dir, "wide");
    {
      ScopedEnv order("SPECTRACK_ITEM_ORDER", "grabbed");  // runs taken from each queue's ticket counter
      grabbed = render(dir, "grabbed");
      ScopedEnv fixed("SPECTRACK_ITEM_ORDER", "blocked");  // a fixed run per work-item
      blocked = render(dir, "blocked");
    }
    ScopedEnv items("SPECTRACK_STAGE_ITEMS", "64");  // one work-group per launch takes its whole queue
    ScopedEnv blocked("SPECTRACK_ITEM_ORDER", "blocked");  // each work-item a run of items
    narrow = render(dir, "narrow");
    ScopedEnv stride("SPECTRACK_ITEM_ORDER", "strided");  // each work-item every 64th item
    strided = render(dir, "strided");
  }
  ASSERT_FALSE(wide.pixels.empty());
  EXPECT_EQ(wide.pixels, narrow.pixels);
  EXPECT_EQ(wide.pixels, strided.pixels);
  EXPECT_EQ(wide.pixels, grabbed.pixels);
  EXPECT_EQ(wide.pixels, blocked.pixels);
  EXPECT_EQ(wide.stats["density_lookups"], grabbed.stats["density_lookups"]);
  EXPECT_EQ(wide.stats["density_lookups"], narrow.stats["density_lookups"]);
  EXPECT_EQ(wide.stats["density_lookups"], strided.stats["density_lookups"]);
  // twin: another seed changes the image, so equal images are not a blind comparison
  const Render other = render(dir, "other", {"--seed", "8"});
  EXPECT_NE(wide.pixels, other.pixels);
}

TEST(Wavefront, LoopPolicyByDeviceType) {
  using spectrack::chunk_launch_items;
  using spectrack::choose_loop_policy;
  const uint64_t many = uint64_t(1) << 30;  // a queue capacity that does not limit the launch
  const spectrack::LoopPolicy cpu = choose_loop_policy(CL_DEVICE_TYPE_CPU);
  EXPECT_FALSE(cpu.sized);  // chunked with runs from the queues' tickets (loop_policy.cpp)
  EXPECT_TRUE(cpu.blocked_items);
  EXPECT_TRUE(cpu.grabbed_items);
  EXPECT_EQ(chunk_launch_items(cpu, 2, 64, many), 2u * 2u * 64u);  // two work-groups per core
  const spectrack::LoopPolicy gpu = choose_loop_policy(CL_DEVICE_TYPE_GPU);
  EXPECT_FALSE(gpu.sized);
  EXPECT_FALSE(gpu.blocked_items);
  EXPECT_EQ(chunk_launch_items(gpu, 132, 64, many), 132u * 2048u);
  EXPECT_EQ(chunk_launch_items(gpu, 132, 64, 1000), 1000u);  // at most the queue's capacity
  EXPECT_EQ(chunk_launch_items(gpu, 0, 64, 0), 1u);
  std::vector<std::pair<std::string, std::string>> defines;
  spectrack::add_loop_policy_define(gpu, defines);
  EXPECT_TRUE(defines.empty());
  spectrack::add_loop_policy_define(cpu, defines);
  EXPECT_EQ(defines, (std::vector<std::pair<std::string, std::string>>{{"ST_ITEMS_BLOCKED", "1"}, {"ST_ITEMS_GRABBED", "1"}}));
  EXPECT_FALSE(gpu.grabbed_items);
  {
    ScopedEnv order("SPECTRACK_ITEM_ORDER", "blocked");  // fixed runs, one per work-item
    const spectrack::LoopPolicy blocked = choose_loop_policy(CL_DEVICE_TYPE_CPU);
    EXPECT_FALSE(blocked.grabbed_items);
    EXPECT_TRUE(blocked.blocked_items);
    std::vector<std::pair<std::string, std::string>> d;
    spectrack::add_loop_policy_define(blocked, d);
    EXPECT_EQ(d, (std::vector<std::pair<std::string, std::string>>{{"ST_ITEMS_BLOCKED", "1"}}));
  }
  {
    ScopedEnv sized("SPECTRACK_LOOP", "sized");
    EXPECT_TRUE(choose_loop_policy(CL_DEVICE_TYPE_GPU).sized);
  }
  {
    ScopedEnv loop("SPECTRACK_LOOP", "chunked");
    ScopedEnv items("SPECTRACK_STAGE_ITEMS", "320");
    ScopedEnv order("SPECTRACK_ITEM_ORDER", "strided");
    const spectrack::LoopPolicy forced = choose_loop_policy(CL_DEVICE_TYPE_CPU);
    EXPECT_FALSE(forced.sized);
    EXPECT_FALSE(forced.blocked_items);
    EXPECT_FALSE(forced.grabbed_items);
    EXPECT_EQ(chunk_launch_items(forced, 2, 64, many), 320u);
  }
  for (auto [name, value] : {std::pair{"SPECTRACK_LOOP", "fast"}, std::pair{"SPECTRACK_STAGE_ITEMS", "12x"},
                             std::pair{"SPECTRACK_STAGE_ITEMS", " -1"}, std::pair{"SPECTRACK_STAGE_ITEMS", "0"},
                             std::pair{"SPECTRACK_STAGE_ITEMS", "99999999999999999999999"},
                             std::pair{"SPECTRACK_ITEM_ORDER", "random"}}) {
    ScopedEnv bad(name, value);
    try {
      choose_loop_policy(CL_DEVICE_TYPE_CPU);
      ADD_FAILURE() << name << "=" << value << " was accepted";
    } catch (const spectrack::Error& e) {
      EXPECT_THAT(e.what(), testing::HasSubstr(std::string(name) + ": '" + value + "'"));
    }
  }
}

}  // namespace
