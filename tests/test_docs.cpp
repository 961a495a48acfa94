// test_docs.cpp: the docs stay true. docs/scene-format.md: every example under docs/examples
// loads and renders at 1 spp on a small tile, every field the parser knows is documented, and
// the default tracker is the one the reference and the README state. docs/cli.md: every flag
// that a subcommand's --help prints is documented, and its reference table of the `render` flags
// is the settings table (integrator/option_table.def), as `render --help` is. README.md, docs/, src/ and kernels/ point
// only into the repository (no design notes outside it, no issue numbers).
#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cstdlib>
#include <cctype>
#include <regex>
#include <set>

#include "cli_util.h"
#include "integrator/option_table.h"
#include "scene/scene.h"

namespace {

using namespace st_cli;
const std::string kSrc = SPECTRACK_SOURCE_DIR;

std::string read_text(const std::string& path) {
  std::ifstream f(path);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

std::vector<std::string> examples() {
  std::vector<std::string> out;
  for (auto& e : fs::directory_iterator(kSrc + "/docs/examples"))
    if (e.path().extension() == ".json") out.push_back(e.path().string());
  std::sort(out.begin(), out.end());
  return out;
}

TEST(DocsExamples, EveryExampleLoadsAndUsesOnlyProjectData) {
  const auto ex = examples();
  ASSERT_GE(ex.size(), 4u);
  for (const std::string& f : ex) {
    SCOPED_TRACE(f);
    spectrack::SceneDesc s = spectrack::load_scene(f);
    EXPECT_FALSE(s.media.empty());
    for (const auto& m : s.media)
      if (m.type == ST_MEDIUM_VDB) EXPECT_NE(m.file.find("/data/volumes/"), std::string::npos) << m.file;
  }
}

TEST(DocsExamples, EveryExampleRendersAtOneSpp) {
  const std::string dir = test_dir();
  for (const std::string& f : examples()) {
    SCOPED_TRACE(f);
    const std::string out = dir + "/" + fs::path(f).stem().string() + ".exr";
    RunOptions o;
    o.timeout_s = 600;  // a cold kernel build on a loaded machine
    Proc p = run({"render", f, "--spp", "1", "--pixel-bounds", "0,16,0,16", "-o", out, "--generic-kernels", "--quiet"}, o);
    ASSERT_TRUE(p.exited && p.code == 0) << p.describe();
    auto in = OIIO::ImageInput::open(out);
    ASSERT_TRUE(in) << OIIO::geterror();
    std::vector<float> px(size_t(in->spec().width) * in->spec().height * in->spec().nchannels);
    ASSERT_TRUE(in->read_image(0, 0, 0, -1, OIIO::TypeDesc::FLOAT, px.data()));
    for (float v : px) ASSERT_TRUE(std::isfinite(v));
  }
}

// Every field name the parser accepts (the lists in src/scene/scene.cpp, scene_media.cpp and
// scene_parser.h) is in the reference.
TEST(DocsExamples, EveryParserFieldIsDocumented) {
  const std::string parser = read_text(kSrc + "/src/scene/scene.cpp") + read_text(kSrc + "/src/scene/scene_media.cpp") +
                             read_text(kSrc + "/src/scene/scene_parser.h");
  const std::string doc = read_text(kSrc + "/docs/scene-format.md");
  ASSERT_FALSE(parser.empty());
  ASSERT_FALSE(doc.empty());
  std::istringstream lines(parser);
  std::string line;
  std::set<std::string> names;
  const std::regex quoted("\"([a-z_0-9]+)\"");
  while (std::getline(lines, line)) {
    if (line.find("fields(") == std::string::npos && line.find("Names all") == std::string::npos &&
        line.find("\"sigma_a\", \"phase\"") == std::string::npos)
      continue;
    for (std::sregex_iterator it(line.begin(), line.end(), quoted), end; it != end; ++it) names.insert((*it)[1]);
  }
  EXPECT_GE(names.size(), 30u);
  for (const std::string& n : names) EXPECT_NE(doc.find("`" + n + "`"), std::string::npos) << "undocumented field " << n;
}

TEST(DocsExamples, OneDefaultTracker) {
  const std::string def = spectrack::tracker_name(spectrack::RenderDesc().tracker);
  EXPECT_EQ(def, "spectral-decomposition");
  const std::string doc = read_text(kSrc + "/docs/scene-format.md");
  EXPECT_NE(doc.find("**The default tracker is `" + def + "`**"), std::string::npos);
  EXPECT_NE(read_text(kSrc + "/README.md").find("`" + def + "` (default)"), std::string::npos);
  // the README sends users to the format inside the repository (OutsideReferences checks the rest)
  EXPECT_NE(read_text(kSrc + "/README.md").find("docs/scene-format.md"), std::string::npos);
  // the shipped scenes use the default tracker
  for (const char* d : {"data/scenes", "bench/scenes", "docs/examples"})
    for (auto& e : fs::directory_iterator(kSrc + "/" + d)) {
      if (e.path().extension() != ".json") continue;
      const json j = json::parse(read_text(e.path().string()));
      if (j.contains("render") && j["render"].contains("tracker"))
        EXPECT_EQ(j["render"]["tracker"].get<std::string>(), def) << e.path();
    }
}

// The flags of one `--help` text: the first token of every line that starts (after spaces) with
// '-', split at commas ("-o,--output TEXT" gives -o and --output).
std::set<std::string> help_flags(const std::string& help) {
  std::set<std::string> out;
  std::istringstream lines(help);
  std::string line;
  const std::regex flag("^--?[A-Za-z][A-Za-z0-9-]*$");
  while (std::getline(lines, line)) {
    const size_t b = line.find_first_not_of(" \t");
    if (b == std::string::npos || line[b] != '-') continue;
    std::string token = line.substr(b, line.find_first_of(" \t", b) - b);
    std::istringstream parts(token);
    std::string part;
    while (std::getline(parts, part, ','))
      if (std::regex_match(part, flag)) out.insert(part);
  }
  return out;
}

// A flag is documented when it appears in docs/cli.md as a whole word (`--spp` does not count
// as documented by `--spp-range`).
bool documents_flag(const std::string& doc, const std::string& f) {
  for (size_t at = doc.find(f); at != std::string::npos; at = doc.find(f, at + 1)) {
    const bool start = at == 0 || !(std::isalnum(static_cast<unsigned char>(doc[at - 1])) || doc[at - 1] == '-');
    const size_t e = at + f.size();
    const bool end = e >= doc.size() || !(std::isalnum(static_cast<unsigned char>(doc[e])) || doc[e] == '-' || doc[e] == '_');
    if (start && end) return true;
  }
  return false;
}

// Every flag of `spectrack --help` and of each subcommand's --help is in docs/cli.md; a flag
// added to src/cli/render_flags.cpp without a line there fails here, naming the subcommand and the flag.
TEST(DocsCli, EveryHelpFlagIsInCliMd) {
  const std::string doc = read_text(kSrc + "/docs/cli.md");
  ASSERT_FALSE(doc.empty());
  size_t total = 0;
  for (const std::vector<std::string>& cmd : std::vector<std::vector<std::string>>{
           {"--help"}, {"render", "--help"}, {"merge", "--help"}, {"devices", "--help"}, {"info", "--help"}}) {
    Proc p = run(cmd);
    ASSERT_TRUE(p.exited && p.code == 0) << p.describe();
    const std::set<std::string> flags = help_flags(p.out);
    EXPECT_FALSE(flags.empty()) << p.describe();
    if (cmd[0] == "render") EXPECT_GE(flags.size(), 30u) << "the --help parser lost the render flags\n" << p.out;
    total += flags.size();
    for (const std::string& f : flags)
      EXPECT_TRUE(documents_flag(doc, f)) << "docs/cli.md does not mention " << f << " of `spectrack " << cmd[0]
                                          << (cmd.size() > 1 ? " --help`" : "`");
  }
  EXPECT_GE(total, 40u);
  // the check itself sees a missing flag
  EXPECT_FALSE(documents_flag(doc, "--no-such-flag"));
  EXPECT_FALSE(documents_flag("`--spp-range A:B`", "--spp"));
  EXPECT_TRUE(documents_flag("`--spp N`", "--spp"));
}

// docs/cli.md's reference table of the `render` flags, between its two markers.
const std::string kTableBegin = "<!-- the settings table: generated from src/integrator/option_table.def -->\n";
const std::string kTableEnd = "<!-- end of the settings table -->";

// The reference table of docs/cli.md is the settings table, row for row (option_table_markdown).
// With SPECTRACK_UPDATE_DOCS=1 the test writes the table into docs/cli.md instead of failing:
//   SPECTRACK_UPDATE_DOCS=1 build/spectrack_tests --gtest_filter='DocsCli.ReferenceTable*'
TEST(DocsCli, ReferenceTableIsTheSettingsTable) {
  const std::string path = kSrc + "/docs/cli.md";
  std::string doc = read_text(path);
  const size_t b = doc.find(kTableBegin), e = doc.find(kTableEnd);
  ASSERT_TRUE(b != std::string::npos && e != std::string::npos && b < e) << "docs/cli.md lost the table's markers";
  const size_t from = b + kTableBegin.size();
  const std::string table = spectrack::option_table_markdown();
  if (std::getenv("SPECTRACK_UPDATE_DOCS")) {
    doc.replace(from, e - from, table);
    std::ofstream(path) << doc;
  }
  EXPECT_EQ(doc.substr(from, e - from), table)
      << "docs/cli.md's reference table differs from src/integrator/option_table.def: run "
         "SPECTRACK_UPDATE_DOCS=1 spectrack_tests --gtest_filter='DocsCli.ReferenceTable*'";
  // one line per row, each naming its flag: a row left out or a doc changed is seen
  const auto& rows = spectrack::render_option_table();
  EXPECT_GE(rows.size(), 40u);
  for (const auto& r : rows) EXPECT_NE(table.find("| `" + r.flags + "` |"), std::string::npos) << r.flags;
  std::string edited = table;
  edited.replace(edited.find("samples per pixel"), 7, "sample ");
  EXPECT_NE(edited, table);
}

// Every scene field the settings table names is one the scene parser reads: set to a value of
// the wrong type it is refused by its own path, never as an unknown field.
TEST(DocsCli, EverySceneFieldOfTheTableIsParsed) {
  size_t fields = 0;
  for (const auto& r : spectrack::render_option_table()) {
    if (r.scene.empty()) continue;
    const size_t dot = r.scene.find('.');
    ASSERT_NE(dot, std::string::npos) << r.scene;
    const std::string section = r.scene.substr(0, dot), key = r.scene.substr(dot + 1);
    const std::string text = "{\"format\": \"spectrack-scene/1\", \"" + section + "\": {\"" + key + "\": {\"x\": 1}}}";
    try {
      spectrack::parse_scene(text, "table.json", ".");
      ADD_FAILURE() << r.scene << ": an object was accepted";
    } catch (const spectrack::Error& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("/" + section + "/" + key), std::string::npos) << r.scene << ": " << what;
      EXPECT_EQ(what.find("unknown field"), std::string::npos) << r.scene << ": " << what;
    }
    ++fields;
  }
  EXPECT_GE(fields, 15u);
  // a field the parser does not read is told apart: the check above can fail
  try {
    spectrack::parse_scene("{\"format\": \"spectrack-scene/1\", \"render\": {\"no_such\": {\"x\": 1}}}", "t.json", ".");
    ADD_FAILURE() << "render.no_such was accepted";
  } catch (const spectrack::Error& e) {
    EXPECT_NE(std::string(e.what()).find("unknown field"), std::string::npos) << e.what();
  }
}

// `render --help` prints each row's help line (option_help): the flags come from the table.
TEST(DocsCli, RenderHelpIsTheSettingsTable) {
  Proc p = run({"render", "--help"});
  ASSERT_TRUE(p.exited && p.code == 0) << p.describe();
  for (const auto& r : spectrack::render_option_table())
    EXPECT_NE(p.out.find(spectrack::option_help(r)), std::string::npos) << r.flags << "\n" << p.out;
  EXPECT_EQ(p.out.find(spectrack::option_help(spectrack::option_row("spp")) + "x"), std::string::npos);
}

// README.md, docs/, src/ and kernels/ point only into the repository: no path into the design
// notes outside it, no upper-case note names other than the repository's own README.md and
// RESULTS.md, and no issue numbers (a reader of the code has no issue tracker).
TEST(DocsCli, OutsideReferences) {
  std::vector<std::string> files = {kSrc + "/README.md"};
  for (const char* d : {"docs", "src", "kernels"})
    for (auto& e : fs::recursive_directory_iterator(kSrc + "/" + d))
      if (e.is_regular_file()) {
        const std::string ext = e.path().extension().string();
        if (ext == ".md" || ext == ".h" || ext == ".cpp" || ext == ".cl") files.push_back(e.path().string());
      }
  ASSERT_GE(files.size(), 40u);
  const std::regex note("\\b([A-Z][A-Z_]{2,})\\.md\\b");
  const std::regex issue("\\b[Ii]ssues? [0-9]+");
  for (const std::string& f : files) {
    const std::string text = read_text(f);
    EXPECT_EQ(text.find("shared/design"), std::string::npos) << f;
    for (std::sregex_iterator it(text.begin(), text.end(), note), end; it != end; ++it) {
      const std::string name = (*it)[1];
      EXPECT_TRUE(name == "README" || name == "RESULTS") << f << " cites " << (*it)[0] << ", a file outside the repository";
    }
    std::smatch m;
    EXPECT_FALSE(std::regex_search(text, m, issue)) << f << " cites \"" << m.str() << "\": point into docs/ instead";
  }
}

}  // namespace
