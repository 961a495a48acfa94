// test_noise_target.cpp: the noise target (integrator/noise.h), the watch of a render
// (integrator/render_watch.h) and resuming a render from its film state (integrator/film_watch.h).
//
// Design: the estimator is checked on films with known sums; a noise-target render must stop at
// or below its target, hold exactly the image of a uniform render of as many samples (bit for
// bit: stopping only chooses n), and agree with a long independent uniform render within 4
// standard errors, while the same comparison with a 3% error injected must fail (the twin). A
// render stopped part-way and resumed from its film state must give the uninterrupted render's
// sums bit for bit, through the library and through the command line (a SIGINT, then --resume).
#include <OpenImageIO/imageio.h>
#include <fmt/format.h>

#include <sys/stat.h>

#include <cmath>

#include "cli_util.h"
#include "guiding/guide_cache.h"
#include "integrator/film_watch.h"
#include "integrator/noise.h"
#include "integrator/render_watch.h"
#include "integrator/renderer.h"

namespace {

using namespace st_cli;
using namespace spectrack;

// Two pixels of 4 samples each (per channel the same), the second black; the first's error is
// known: samples 1, 2, 3, 6 have mean 3, sample variance 14/3, SE sqrt(14/3 / 4).
TEST(NoiseEstimate, IsTheStandardErrorOverTheMeanOfTheNoisyPixels) {
  const double s1 = 1 + 2 + 3 + 6, s2 = 1 + 4 + 9 + 36;
  std::vector<double> sum = {s1, s1, s1, 0, 0, 0}, m2 = {s2, s2, s2, 0, 0, 0};
  NoiseEstimate e = estimate_noise(sum.data(), 3, m2.data(), 3, 2, 4);
  EXPECT_EQ(e.pixels, 1u);  // the black pixel does not count
  EXPECT_NEAR(e.error, std::sqrt(14.0 / 3.0 / 4.0) / 3.0, 1e-12);
  EXPECT_TRUE(e.measured);
  EXPECT_FALSE(estimate_noise(sum.data(), 3, m2.data(), 3, 2, 1).measured);  // one sample: no sample variance
  // a constant pixel has no error to measure; a dim noisy one counts against the floor
  sum = {s1, s1, s1, 40, 40, 40, 0.04, 0.04, 0.04};
  m2 = {s2, s2, s2, 400, 400, 400, 0.0016 * 4, 0.0016 * 4, 0.0016 * 4};
  m2[6] = m2[7] = m2[8] = 0.01;  // samples of a dim pixel that vary
  e = estimate_noise(sum.data(), 3, m2.data(), 3, 3, 4);
  EXPECT_EQ(e.pixels, 2u);
  const double dim_se = std::sqrt((0.01 - 0.0016 / 4) / 12.0), floor = kNoiseFloor * (3.0 + 0.01) / 2.0;
  // the 95th percentile of two values is the larger one
  EXPECT_NEAR(e.error, std::max(std::sqrt(14.0 / 3.0 / 4.0) / 3.0, dim_se / floor), 1e-9);
  // the schedule: never below the floor, at least one more sample, at most twice as many
  EXPECT_EQ(next_noise_check(1.0, 4, 0.1), kNoiseMinSpp);
  EXPECT_EQ(next_noise_check(0.2, 16, 0.1), 32);
  EXPECT_EQ(next_noise_check(0.12, 100, 0.1), 144);
  EXPECT_EQ(next_noise_check(0.1, 100, 0.1), 101);
}

RenderResult render_with(const SceneDesc& scene, RenderOptions o) {
  Renderer r(scene, o);
  return r.render();
}

// A render stopped at n samples holds the image of the uniform render `uniform_options` (n samples),
// bit for bit, and agrees with a long unguided render of another seed within 4 SE; 3% off does not.
void expect_uniform_image_without_bias(const SceneDesc& scene, const RenderResult& stopped,
                                       const RenderOptions& uniform_options) {
  const RenderResult uniform = render_with(scene, uniform_options);
  ASSERT_EQ(uniform.rgb.size(), stopped.rgb.size());
  for (size_t i = 0; i < uniform.rgb.size(); ++i) ASSERT_EQ(uniform.rgb[i], stopped.rgb[i]) << "value " << i;
  RenderOptions lo = st_test::quiet_options(1024);
  lo.seed = 977;
  const RenderResult reference = render_with(scene, lo);
  EXPECT_LT(st_test::max_z(stopped, reference), 4.0);
  EXPECT_GT(st_test::max_z(stopped, reference, 1.03), 4.0) << "the twin: a 3% error must be seen";
}

TEST(NoiseTarget, StopsBelowTheTargetWithTheUniformImageOfItsSamplesAndNoBias) {
  const std::string dir = test_dir();
  const SceneDesc scene = st_test::scene_from_json(small_noise_scene(dir), dir);
  RenderOptions o = st_test::quiet_options(4096);
  o.noise_target = 0.04;
  o.aovs = ST_AOV_BIT(VARIANCE);
  WatchConfig c;
  c.noise_target = 0.04;
  c.spp = 4096;
  RenderWatch watch(c);
  o.watch = &watch;
  const RenderResult stopped = render_with(scene, o);
  ASSERT_TRUE(stopped.noise_target_reached);
  EXPECT_FALSE(stopped.interrupted);
  EXPECT_GE(stopped.spp_done, kNoiseMinSpp);
  EXPECT_LT(stopped.spp_done, 4096);
  const NoiseEstimate e = estimate_film_noise(stopped.sum, stopped.aov_sum, stopped.aov_channels, stopped.spp_done);
  EXPECT_LE(e.error, 0.04);
  EXPECT_GT(e.pixels, 100u);
  // stopping only chose n: the image is the uniform render of n samples, and unbiased
  expect_uniform_image_without_bias(scene, stopped, st_test::quiet_options(int(stopped.spp_done)));
}

// A watch that hands everything to a RenderWatch and keeps what it was shown: the sample counts it
// was asked about and the last film it saw.
struct Seen : FilmWatch {
  RenderWatch& inner;
  std::vector<int64_t> asked;
  RenderResult last;
  explicit Seen(RenderWatch& w) : inner(w) {}
  int wants(int64_t n) override {
    asked.push_back(n);
    return inner.wants(n);
  }
  bool see(const RenderResult& film, const FilmState* st) override {
    last = film;
    return inner.see(film, st);
  }
  int64_t samples_needed() const override { return inner.samples_needed(); }
};

// With guiding the image holds the training pass's samples besides the stage loop's own: the watch
// judges that image, so the render stops as soon as the image (not the own samples alone) reaches
// the target, and the image is the uniform guided render of as many samples.
TEST(NoiseTarget, CountsTheGuidesTrainingSamples) {
  const std::string dir = test_dir();
  const SceneDesc scene = st_test::scene_from_json(small_noise_scene(dir), dir);
  auto guided = [](int spp) {
    RenderOptions o = st_test::quiet_options(spp);
    o.guiding = kGuidingOn;
    o.aovs = ST_AOV_BIT(VARIANCE);
    return o;
  };
  RenderOptions o = guided(4096);
  o.noise_target = 0.04;
  WatchConfig c;
  c.noise_target = 0.04;
  c.spp = 4096;
  RenderWatch inner(c);
  Seen watch(inner);
  o.watch = &watch;
  const RenderResult stopped = render_with(scene, o);
  ASSERT_TRUE(stopped.noise_target_reached);
  ASSERT_TRUE(stopped.guide.used);
  int64_t T = 0;  // the training samples the image holds
  for (int spp : kGuideTrainingSpp) T += spp;
  EXPECT_LT(stopped.spp_done, 4096);
  // every count the watch was asked about holds the training samples, and the film it stopped on
  // is the one returned, bit for bit
  ASSERT_FALSE(watch.asked.empty());
  EXPECT_GT(watch.asked.front(), T);
  EXPECT_EQ(watch.last.spp_done, stopped.spp_done);
  ASSERT_EQ(watch.last.sum.size(), stopped.sum.size());
  for (size_t i = 0; i < stopped.sum.size(); ++i) ASSERT_EQ(watch.last.sum[i], stopped.sum[i]) << "sum " << i;
  ASSERT_TRUE(inner.last_estimate());
  const NoiseEstimate e = estimate_film_noise(stopped.sum, stopped.aov_sum, stopped.aov_channels, stopped.spp_done);
  EXPECT_EQ(inner.last_estimate()->error, e.error);
  EXPECT_LE(e.error, 0.04);
  // the image is the uniform guided render of its samples, and unbiased
  expect_uniform_image_without_bias(scene, stopped, guided(int(stopped.spp_done)));
}

// A watch that stops the render at a sample count and keeps the film state it ends with; or
// resumes from a state.
struct StopAt : FilmWatch {
  int64_t at = 0;
  std::optional<FilmState> kept;
  const FilmState* from = nullptr;
  int wants(int64_t n) override { return at > 0 && n >= at ? kFilm : kNothing; }
  bool see(const RenderResult&, const FilmState*) override { return true; }
  bool wants_final_state() const override { return true; }
  void final_state(const FilmState& s) override { kept = s; }
  const FilmState* resume() const override { return from; }
};

TEST(Resume, ContinuesTheSampleSequenceToTheUninterruptedSumsBitForBit) {
  const std::string dir = test_dir();
  const SceneDesc scene = st_test::scene_from_json(small_noise_scene(dir), dir);
  RenderOptions o = st_test::quiet_options(48);
  o.aovs = ST_AOV_BIT(VARIANCE) | ST_AOV_BIT(ALPHA);
  o.path_slots = 4096;  // several batches of a few samples
  const RenderResult whole = render_with(scene, o);
  StopAt first;
  first.at = 13;
  RenderOptions a = o;
  a.watch = &first;
  const RenderResult part = render_with(scene, a);
  ASSERT_TRUE(first.kept);
  ASSERT_LT(part.spp_done, 48);
  EXPECT_EQ(first.kept->samples_done, part.spp_done);
  // the state survives the disk
  write_film_state(dir + "/state", *first.kept, "key");
  EXPECT_THAT(st_test::error_of([&] { read_film_state(dir + "/state", "another key"); }), HasSubstr("another render"));
  // a mismatch names the fields that differ, values with spaces whole (the majorant grid's)
  RenderIdentity id;
  id.scene_hash = "abc";
  const FilmWindow w{0, 0, 4, 4};
  const std::string key = film_state_key(id, w, 0, 48);
  EXPECT_THAT(key, HasSubstr("scene_hash=abc film=")) << key;
  write_film_state(dir + "/keyed", *first.kept, key);
  RenderIdentity other = id;
  other.majorant = majorant_identity(8, kDefaultMajorantBlock, std::nullopt);
  other.seed = id.seed + 1;
  const std::string msg = st_test::error_of([&] { read_film_state(dir + "/keyed", film_state_key(other, w, 0, 48)); });
  EXPECT_THAT(msg, HasSubstr("it differs in seed (the file's " + std::to_string(id.seed) + ", this render's " +
                             std::to_string(other.seed) + "), majorant (the file's " + id.majorant + ", this render's " +
                             other.majorant + ") (remove it")) << msg;
  EXPECT_NO_THROW(read_film_state(dir + "/keyed", key));  // the twin: its own key reads
  const FilmState loaded = read_film_state(dir + "/state", "key");
  StopAt second;
  second.from = &loaded;
  RenderOptions b = o;
  b.watch = &second;
  const RenderResult resumed = render_with(scene, b);
  EXPECT_EQ(resumed.spp_done, 48);
  EXPECT_FALSE(resumed.interrupted);
  ASSERT_EQ(resumed.sum.size(), whole.sum.size());
  for (size_t i = 0; i < whole.sum.size(); ++i) ASSERT_EQ(resumed.sum[i], whole.sum[i]) << "sum " << i;
  for (size_t i = 0; i < whole.aov_sum.size(); ++i) ASSERT_EQ(resumed.aov_sum[i], whole.aov_sum[i]) << "layer sum " << i;
  // the twin: the stopped part alone is not the whole render
  size_t differ = 0, lit = 0;  // a transparent film's background is 0 in both
  for (size_t i = 0; i < whole.sum.size(); ++i) differ += part.sum[i] != whole.sum[i], lit += whole.sum[i] != 0;
  EXPECT_GT(lit, whole.sum.size() / 4);
  EXPECT_GE(differ, lit * 9 / 10);
}

// The film state's key names every choice a merge compares (film.h recorded_choices): a state of a
// render with another shutter, budget, majorant grid, equi-angular setting or framed camera is
// another render's. The options reach the key through the settings (the twin: equal options, equal keys).
TEST(Resume, TheFilmStatesKeyNamesEveryChoiceAMergeCompares) {
  const std::string dir = test_dir();
  const SceneDesc scene = st_test::scene_from_json(small_noise_scene(dir), dir);
  const RenderOptions o = st_test::quiet_options(8);
  const RenderSettings s = resolve_settings(scene, o);
  const RenderIdentity id = render_identity(s);
  const std::string key = film_state_key(id, s.window, 0, 8);
  EXPECT_EQ(film_state_key(render_identity(resolve_settings(scene, o)), s.window, 0, 8), key);
  for (const RecordedChoice& c : recorded_choices()) {
    RenderIdentity other = id;
    other.*c.field += "x";
    EXPECT_NE(film_state_key(other, s.window, 0, 8), key) << c.key;
  }
  auto key_with = [&](const std::function<void(RenderOptions&)>& change) {
    RenderOptions v = o;
    change(v);
    const RenderSettings vs = resolve_settings(scene, v);
    return film_state_key(render_identity(vs), vs.window, 0, 8);
  };
  EXPECT_NE(key_with([](RenderOptions& v) { v.shutter = std::array<double, 2>{0.0, 1.0}; }), key);
  EXPECT_NE(key_with([](RenderOptions& v) { v.iteration_budget = 7; }), key);
  EXPECT_NE(key_with([](RenderOptions& v) { v.majorant_cell = 4; }), key);
  EXPECT_NE(key_with([](RenderOptions& v) { v.majorant_block = 0; }), key);
  EXPECT_NE(key_with([](RenderOptions& v) { v.majorant_step_cost = 50.0; }), key);
  EXPECT_NE(key_with([](RenderOptions& v) { v.equiangular = kEquiangularOn; }), key);
  EXPECT_NE(key_with([](RenderOptions& v) { v.transmittance = ST_TRANSMITTANCE_RAY_MARCHING; }), key);
  EXPECT_EQ(key_with([](RenderOptions& v) { v.iteration_budget = kDefaultIterationBudget; }), key);
}

// A damaged film state is refused naming the file, never resumed into a wrong image: a changed
// sample count, flipped bits, a non-finite value, a header cut short, a FIFO, a folder.
TEST(Resume, DamagedFilmStatesAreRefusedNamingTheFile) {
  const std::string dir = test_dir();
  FilmState st;
  st.sample_begin = 0;
  st.samples_done = 5;
  st.npix = 3;
  st.layers = 2;
  st.film.assign(2 * st.layers * st.npix * 4, 0.25f);
  const std::string good = dir + "/state";
  write_film_state(good, st, "key");
  EXPECT_EQ(read_film_state(good, "key").film, st.film);  // the twin: the file itself reads back
  std::string bytes;
  {
    std::ifstream in(good, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
  }
  auto refused = [&](const std::string& name, const std::string& content) {
    std::ofstream(dir + "/" + name, std::ios::binary) << content;
    return st_test::error_of([&] { read_film_state(dir + "/" + name, "key"); });
  };
  std::string count = bytes;
  count.replace(count.find("0 5 3 2"), 7, "0 4 3 2");  // fewer samples than the sums hold: a darker image
  EXPECT_THAT(refused("count", count), AllOf(HasSubstr(dir + "/count"), HasSubstr("damaged")));
  std::string flipped = bytes;
  flipped[flipped.size() - 3] ^= 0x40;
  EXPECT_THAT(refused("flipped", flipped), AllOf(HasSubstr(dir + "/flipped"), HasSubstr("damaged")));
  EXPECT_THAT(refused("cut", bytes.substr(0, bytes.find('\n') + 5)), HasSubstr("header is cut short"));
  FilmState nan = st;
  nan.film[7] = std::nanf("");
  write_film_state(dir + "/nan", nan, "key");  // its digest is right: the value itself is refused
  EXPECT_THAT(st_test::error_of([&] { read_film_state(dir + "/nan", "key"); }),
              AllOf(HasSubstr(dir + "/nan"), HasSubstr("non-finite")));
  ASSERT_EQ(::mkfifo((dir + "/fifo").c_str(), 0600), 0);
  EXPECT_THAT(st_test::error_of([&] { read_film_state(dir + "/fifo", "key"); }), HasSubstr("not a regular file"));
  fs::create_directories(dir + "/folder");
  EXPECT_THAT(st_test::error_of([&] { read_film_state(dir + "/folder", "key"); }), HasSubstr("not a regular file"));
}

std::string meta_of(const std::string& path, const std::string& key) {
  auto in = OIIO::ImageInput::open(path);
  return in ? in->spec().get_string_attribute("spectrack:" + key, "<missing>") : "<unreadable>";
}

int meta_int(const std::string& path, const std::string& key) {
  auto in = OIIO::ImageInput::open(path);
  return in ? in->spec().get_int_attribute("spectrack:" + key, -1) : -2;
}

TEST(CliNoiseTarget, RecordsTheTargetTheErrorReachedAndWhyItStopped) {
  const std::string dir = test_dir();
  const std::string scene = write_scene(dir, "scene.json", small_noise_scene(dir));
  RunOptions ro;
  ro.timeout_s = 240;
  Proc p = run({"render", scene, "-o", dir + "/n.exr", "--noise-target", "0.05", "--spp", "4096", "--stats-json",
                dir + "/n.json"}, ro);
  ASSERT_TRUE(p.exited && p.code == 0) << p.describe();
  EXPECT_THAT(p.out, HasSubstr("noise target reached"));
  EXPECT_EQ(meta_of(dir + "/n.exr", "stop_reason"), "noise-target");
  EXPECT_EQ(meta_int(dir + "/n.exr", "interrupted"), 0);
  const json j = json::parse(std::ifstream(dir + "/n.json"));
  EXPECT_EQ(j.value("stop_reason", ""), "noise-target");
  EXPECT_NEAR(j.value("noise_target", 0.0), 0.05, 1e-7);
  EXPECT_LE(j.value("noise_error", 1.0), 0.05);
  EXPECT_GT(j.value("noise_error", 0.0), 0.0);
  EXPECT_LT(j.value("spp", 0), 4096);
  // a cap below what the target needs: stops at --spp, the error reached recorded
  p = run({"render", scene, "-o", dir + "/c.exr", "--noise-target", "0.001", "--spp", "20", "--stats-json",
           dir + "/c.json", "--quiet"}, ro);
  ASSERT_TRUE(p.exited && p.code == 0) << p.describe();
  const json k = json::parse(std::ifstream(dir + "/c.json"));
  EXPECT_EQ(k.value("spp", 0), 20);
  EXPECT_EQ(k.value("stop_reason", "x"), "spp");
  EXPECT_GT(k.value("noise_error", 0.0), 0.001);
  // a film of one batch is first looked at after its last sample: a target met there is reached
  // (the twin above, 0.001 at 20 spp, is missed)
  p = run({"render", scene, "-o", dir + "/once.exr", "--noise-target", "0.5", "--spp", "32", "--path-slots", "65536",
           "--stats-json", dir + "/once.json", "--quiet"}, ro);
  ASSERT_TRUE(p.exited && p.code == 0) << p.describe();
  const json once = json::parse(std::ifstream(dir + "/once.json"));
  EXPECT_EQ(once.value("spp", 0), 32);
  EXPECT_LE(once.value("noise_error", 1.0), 0.5);
  EXPECT_EQ(once.value("stop_reason", "x"), "noise-target");
  EXPECT_EQ(meta_of(dir + "/once.exr", "stop_reason"), "noise-target");
  // one sample per pixel measures no noise: the target is missed at --spp, uniform or adaptive, and no
  // error is recorded (0% would read as reached)
  for (const std::vector<std::string>& extra : {std::vector<std::string>{}, std::vector<std::string>{"--adaptive"}}) {
    std::vector<std::string> a = {"render", scene, "-o", dir + "/one.exr", "--noise-target", "0.1", "--spp", "1",
                                  "--stats-json", dir + "/one.json"};
    a.insert(a.end(), extra.begin(), extra.end());
    p = run(a, ro);
    ASSERT_TRUE(p.exited && p.code == 0) << p.describe();
    EXPECT_THAT(p.out, HasSubstr("noise target missed at --spp"));
    EXPECT_THAT(p.out, testing::Not(HasSubstr("noise 0%")));
    const json one = json::parse(std::ifstream(dir + "/one.json"));
    EXPECT_EQ(one.value("stop_reason", "x"), "spp") << extra.size();
    EXPECT_FALSE(one.contains("noise_error")) << one.dump(2);
  }
  // a target out of reach stops at the time limit; the progress lines show the estimate
  p = run({"render", scene, "-o", dir + "/t.exr", "--noise-target", "0.0001", "--spp", "1000000", "--time-limit", "7",
           "--stats-json", dir + "/t.json"}, ro);
  ASSERT_TRUE(p.exited && p.code == 0) << p.describe();
  EXPECT_THAT(p.out, HasSubstr("(target 0.01%)"));
  const json t = json::parse(std::ifstream(dir + "/t.json"));
  EXPECT_EQ(t.value("stop_reason", ""), "time-limit");
  EXPECT_GT(t.value("noise_error", 0.0), 0.0001);
  // refusals: a scene value out of range names its field; shards and several devices exit 2
  json bad = small_noise_scene(dir);
  bad["render"]["noise_target"] = 2.0;
  p = run({"render", write_scene(dir, "bad.json", bad), "-o", dir + "/b.exr", "--quiet"});
  EXPECT_EQ(p.code, 1) << p.describe();
  EXPECT_THAT(p.out, HasSubstr("/render/noise_target"));
  p = run({"render", scene, "-o", dir + "/s.exr", "--noise-target", "0.05", "--spp-range", "0:8", "--quiet"});
  EXPECT_EQ(p.code, 2) << p.describe();
  p = run({"render", scene, "-o", dir + "/d.exr", "--noise-target", "0.05", "--device", "0:0,0:0", "--quiet"});
  EXPECT_EQ(p.code, 2) << p.describe();
}

TEST(CliResume, AnInterruptedCheckpointedRenderResumesToTheUninterruptedImage) {
  const std::string dir = test_dir();
  json s = small_noise_scene(dir);
  s["film"]["width"] = 96;
  s["film"]["height"] = 64;
  const std::string scene = write_scene(dir, "scene.json", s);
  RunOptions ro;
  ro.timeout_s = 300;
  const std::vector<std::string> common = {"render", scene, "--spp", "400", "--path-slots", "8192", "--aov", "variance"};
  auto with = [&](std::vector<std::string> extra) {
    std::vector<std::string> v = common;
    v.insert(v.end(), extra.begin(), extra.end());
    return v;
  };
  Proc w = run(with({"-o", dir + "/whole.exr", "--quiet"}), ro);
  ASSERT_TRUE(w.exited && w.code == 0) << w.describe();
  // interrupted after some progress, with checkpoints: the image and its film state are written
  RunOptions io = ro;
  io.signal = SIGINT;
  // 0.7 s after the first progress line (the stage loop runs): a progress line of 10% or more
  // comes only every 5 s, after the whole render on an idle machine
  io.signal_after_text = "progress: ";
  io.signal_delay_s = 0.7;
  std::vector<std::string> args = with({"-o", dir + "/part.exr", "--checkpoint", "0.5"});
  Proc i = run(args, io);
  ASSERT_TRUE(i.exited) << i.describe();
  ASSERT_EQ(i.code, 130) << "the render finished before the signal: make it longer\n" << i.describe();
  ASSERT_TRUE(fs::exists(dir + "/part.exr.resume")) << i.describe();
  EXPECT_EQ(meta_int(dir + "/part.exr", "interrupted"), 1);
  // resumed without --checkpoint: a render that completes removes the state it resumed from
  args = with({"-o", dir + "/part.exr", "--resume"});
  Proc r = run(args, ro);
  ASSERT_TRUE(r.exited && r.code == 0) << r.describe();
  EXPECT_THAT(r.out, HasSubstr("resuming from"));
  EXPECT_FALSE(fs::exists(dir + "/part.exr.resume")) << "a completed render leaves no state";
  const std::vector<float> a = image_pixels(dir + "/whole.exr"), b = image_pixels(dir + "/part.exr");
  ASSERT_EQ(a.size(), b.size());
  ASSERT_FALSE(a.empty());
  size_t differ = 0;
  for (size_t k = 0; k < a.size(); ++k) differ += a[k] != b[k];
  EXPECT_EQ(differ, 0u) << "the resumed image differs from the uninterrupted one";
  // a state of another render is refused, naming the file
  args = with({"-o", dir + "/part.exr", "--resume", "--quiet"});
  std::ofstream(dir + "/part.exr.resume") << "spectrack-film-state/2\nscene_hash=x\n0 1 1 1\n0\n";
  Proc bad = run(args, ro);
  EXPECT_EQ(bad.code, 1) << bad.describe();
  EXPECT_THAT(bad.out, HasSubstr("part.exr.resume: the film state belongs to another render: it differs in scene_hash "
                                 "(the file's x, this render's "));
  EXPECT_THAT(bad.out, HasSubstr("seed (the file's none, this render's ")) << bad.out;
}

}  // namespace

namespace {

// The preview is written during the render, whole: a render killed (no chance to write at the end)
// leaves a readable preview of the samples done by then.
TEST(CliPreview, IsRewrittenDuringTheRender) {
  const std::string dir = test_dir();
  const std::string scene = write_scene(dir, "scene.json", small_noise_scene(dir));
  st_cli::RunOptions o;
  o.timeout_s = 180;
  o.signal = SIGKILL;
  o.signal_after_text = "progress: 0%";
  o.signal_delay_s = 18.0;  // several preview periods (kPreviewSeconds), with room for a loaded machine
  Proc p = run({"render", scene, "-o", dir + "/k.exr", "--spp", "1000000", "--preview", dir + "/k.png"}, o);
  ASSERT_TRUE(p.signal_sent) << p.describe();
  EXPECT_TRUE(p.signaled) << p.describe();
  EXPECT_FALSE(fs::exists(dir + "/k.exr")) << "the image is written at the end only";
  int channels = 0;
  const std::vector<float> px = image_pixels(dir + "/k.png", &channels);
  ASSERT_EQ(px.size(), size_t(24 * 16 * channels));
  double sum = 0;
  for (float v : px) sum += v;
  EXPECT_GT(sum, 0.0) << "the preview holds the samples done";
}

}  // namespace
