// warning.h: how the library's parts warn the user of a scene or file that renders, but maybe
// not as meant: "warning: TEXT" on stderr, once per process for each text (a grid loaded twice,
// by `info`'s report and by the pack that follows it, warns once), and not at all once the
// command asked for quiet output (-q: set_warnings_quiet). Errors are thrown, never warned.
// A sink (set_warning_sink) takes the texts instead of stderr: the Python module queues them and
// writes them to sys.stderr, where a notebook shows them.
#pragma once
#include <functional>
#include <string>

namespace spectrack {

void warn(const std::string& text);
void set_warnings_quiet(bool quiet);
// Where each new warning's text goes instead of stderr (called under a lock, from any thread: it
// must not block on other locks); an empty function restores stderr.
void set_warning_sink(std::function<void(const std::string& text)> sink);

}  // namespace spectrack
