// warning.h: how the library's parts warn the user of a scene or file that renders, but maybe
// not as meant: "warning: TEXT" on stderr, once per process for each text (a grid loaded twice,
// by `info`'s report and by the pack that follows it, warns once), and not at all once the
// command asked for quiet output (-q: set_warnings_quiet). Errors are thrown, never warned.
#pragma once
#include <string>

namespace spectrack {

void warn(const std::string& text);
void set_warnings_quiet(bool quiet);

}  // namespace spectrack
