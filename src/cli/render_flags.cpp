// render_flags.cpp: the flags of `spectrack render`, one per row of the settings table
// (integrator/option_table.def, in its order: what is rendered, how it is estimated, how it runs).
// A row's check becomes a CLI11 validator (cli/options.h: a bad value exits 2 with the reason) and
// its help is option_help (the doc, the default and the scene field), which docs/cli.md's
// reference table repeats (tests/test_docs.cpp keeps the two equal).
#include <string>

#include "cli/options.h"
#include "cli/render.h"
#include "integrator/option_table.h"

namespace spectrack {
namespace {

// The CLI11 validator of a row's check.
CLI::Validator validator(const OptionRow& row) {
  const OptionCheck& c = row.check;
  switch (c.kind) {
    case OptionCheck::kInteger: return integer_in(int64_t(c.lo), int64_t(c.hi));
    case OptionCheck::kNumber: return finite_range(c.lo, c.hi);
    case OptionCheck::kNames: {
      std::string what = row.member;
      for (char& ch : what) ch = ch == '_' ? ' ' : ch;
      return one_of(what, c.names);
    }
    case OptionCheck::kForm: {
      auto reader = c.reader;
      return CLI::Validator([reader](std::string& v) { return reader(v); }, c.meta);
    }
    default: return CLI::Validator();  // kText, kFlag: no check (add_row)
  }
}

// One row as a flag of `render`, bound to its RenderArgs member.
template <class Slot>
CLI::Option* add_row(CLI::App* render, const OptionRow& row, Slot& slot) {
  if constexpr (std::is_same_v<Slot, bool>) return render->add_flag(row.flags, slot, option_help(row));
  else if (row.check.kind == OptionCheck::kText) return render->add_option(row.flags, slot, option_help(row))->type_name(row.check.meta);
  else return render->add_option(row.flags, slot, option_help(row))->check(validator(row));
}

}  // namespace

CLI::App* add_render_command(CLI::App& app, RenderArgs& ra) {
  auto* render = app.add_subcommand("render", "render a scene file to EXR or PNG");
  render->add_option("scene", ra.scene, "scene file (spectrack-scene/1 JSON)")->required();
#define ST_OPTION(member, ...) add_row(render, option_row(#member), ra.member);
#include "integrator/option_table.def"
#undef ST_OPTION
  render->get_option("--spp-range")->excludes("--spp");  // a shard sets its own samples
  return render;
}

}  // namespace spectrack
