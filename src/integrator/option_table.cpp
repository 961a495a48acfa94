// option_table.cpp: the rows of option_table.def as data (see option_table.h), their help lines
// and docs/cli.md's reference table.
#include "integrator/option_table.h"

#include <fmt/format.h>

#include <array>

#include "scene/scene.h"
#include "util/option_text.h"

namespace spectrack {
namespace {

// The checks of the table's rows (option_table.def).
OptionCheck integer(int64_t lo, int64_t hi) { return {OptionCheck::kInteger, double(lo), double(hi), {}, "INT", nullptr}; }
OptionCheck number(double lo, double hi) { return {OptionCheck::kNumber, lo, hi, {}, "NUMBER", nullptr}; }
OptionCheck names(std::vector<std::string> list) { return {OptionCheck::kNames, 0, 0, std::move(list), "NAME", nullptr}; }
OptionCheck flag() { return {OptionCheck::kFlag, 0, 0, {}, "", nullptr}; }
OptionCheck text(const char* meta) { return {OptionCheck::kText, 0, 0, {}, meta, nullptr}; }
OptionCheck form(const char* meta, std::string (*reader)(const std::string&)) {
  return {OptionCheck::kForm, 0, 0, {}, meta, reader};
}

// The readers of the text forms (util/option_text.h), as a row's check calls them.
std::string spp_range_reader(const std::string& t) {
  int64_t a = 0, b = 0;
  return check_spp_range(t, &a, &b);
}
std::string pixel_bounds_reader(const std::string& t) {
  std::array<int, 4> b{};
  return check_pixel_bounds(t, &b);
}
std::string frames_reader(const std::string& t) {
  long long a = 0, b = 0;
  return check_frames(t, &a, &b);
}
std::string shutter_reader(const std::string& t) {
  std::array<double, 2> s{};
  return check_shutter(t, &s);
}
std::string preview_reader(const std::string& t) { return check_png_name(t); }
std::string device_reader(const std::string& t) { return check_not_blank(t, "device"); }

std::vector<std::string> guiding_name_list() {
  return {guiding_name(kGuidingOff), guiding_name(kGuidingOn), guiding_name(kGuidingAuto)};
}

std::vector<OptionRow> make_rows() {
  std::vector<OptionRow> rows;
#define ST_OPTION(member, Type, flags, scene, default_text, check, doc) \
  rows.push_back(OptionRow{#member, flags, scene, default_text, check, doc});
#include "integrator/option_table.def"
#undef ST_OPTION
  return rows;
}

// A Markdown table cell: '|' escaped.
std::string cell(const std::string& s) {
  std::string out;
  for (char c : s) out += c == '|' ? std::string("\\|") : std::string(1, c);
  return out;
}

}  // namespace

std::string OptionRow::flag() const {
  const size_t comma = flags.rfind(',');
  return comma == std::string::npos ? flags : flags.substr(comma + 1);
}

const std::vector<OptionRow>& render_option_table() {
  static const std::vector<OptionRow> rows = make_rows();
  return rows;
}

const OptionRow& option_row(const std::string& member) {
  for (const OptionRow& r : render_option_table())
    if (r.member == member) return r;
  throw Error("internal: the settings table has no option '" + member + "'");
}

std::string option_help(const OptionRow& row) {
  std::string notes;
  // a flag overrides its scene field, except --aov, whose layers are added to the list film.aovs
  if (!row.scene.empty()) notes = (row.member == "aov" ? "adds to " : "overrides ") + row.scene;
  if (!row.default_text.empty()) notes += (notes.empty() ? "" : "; ") + std::string("default: ") + row.default_text;
  return notes.empty() ? row.doc : row.doc + " (" + notes + ")";
}

std::string option_table_markdown() {
  std::string md = "| flag | value | scene field | default | what it does |\n|---|---|---|---|---|\n";
  for (const OptionRow& r : render_option_table()) {
    const OptionCheck& c = r.check;
    std::string value;
    switch (c.kind) {
      case OptionCheck::kInteger: value = fmt::format("integer in [{}, {}]", int64_t(c.lo), int64_t(c.hi)); break;
      case OptionCheck::kNumber: value = fmt::format("number in [{}, {}]", c.lo, c.hi); break;
      case OptionCheck::kNames:
        for (const std::string& n : c.names) value += (value.empty() ? "" : ", ") + ("`" + n + "`");
        break;
      case OptionCheck::kFlag: value = "(none)"; break;
      case OptionCheck::kText:
      case OptionCheck::kForm: value = "`" + c.meta + "`"; break;
    }
    md += fmt::format("| `{}` | {} | {} | {} | {} |\n", cell(r.flags), cell(value),
                      r.scene.empty() ? "" : "`" + r.scene + "`", cell(r.default_text), cell(r.doc));
  }
  return md;
}

}  // namespace spectrack
