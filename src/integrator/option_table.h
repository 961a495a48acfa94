// option_table.h: the settings table: every option of `spectrack render` once, with its flag, the
// scene JSON field it overrides, its type, default, range or choices and one-line doc.
//
// Design: the rows are option_table.def, an X-macro list (ST_OPTION(member, Type, flags, scene
// field, default, check, doc)), read in four places, so an option is one row:
//   - RenderArgs (cli/render.h) gets one member per row, std::optional<Type> for numbers (no
//     "not given" sentinels; flags are bool, texts std::string);
//   - add_render_command (cli/render_flags.cpp) makes each row a CLI11 flag with its check and its
//     help (option_help: the doc, the default and the scene field);
//   - render_option_table() below holds the rows as data, for the reference table of docs/cli.md
//     (option_table_markdown; tests/test_docs.cpp keeps the two equal) and for the scene parser's
//     choices of the render.* and film.* names (option_choices);
//   - the defaults are the constants the code uses (settings.h, FilmDesc, RenderDesc), printed,
//     so the help and docs cannot drift from them.
// The resolved choices a render records (EXR metadata, statistics, merge's comparison) are one
// list too: recorded_choices (film/film.h).
#pragma once
#include <string>
#include <vector>

#include "integrator/settings.h"

namespace spectrack {

// How a row's value is checked: an integer or a number in [lo, hi], one of `names`, a flag (no
// value), free text, or a text form read by `reader` ("" for a good value, else the reason).
struct OptionCheck {
  enum Kind { kInteger, kNumber, kNames, kFlag, kText, kForm } kind = kText;
  double lo = 0, hi = 0;
  std::vector<std::string> names;
  std::string meta;  // what the value looks like in --help ("A:B", "FILE")
  std::string (*reader)(const std::string&) = nullptr;
};

struct OptionRow {
  std::string member;   // RenderArgs' member ("light_sampling")
  std::string flags;    // CLI11's names ("-o,--output")
  std::string scene;    // the scene field it overrides ("render.light_sampling"), or ""
  std::string default_text;  // "" when none
  OptionCheck check;
  std::string doc;
  std::string flag() const;  // the long flag ("--output")
};

// Every row, in the order of option_table.def (the order of `render --help`).
const std::vector<OptionRow>& render_option_table();
// The row of `member`; throws Error for a member the table does not have.
const OptionRow& option_row(const std::string& member);
// The help line of a row: its doc, then "(default ...; scene ...)".
std::string option_help(const OptionRow& row);
// The reference table of docs/cli.md (Markdown; one line per row).
std::string option_table_markdown();

}  // namespace spectrack
