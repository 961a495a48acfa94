// warnings_py.h: the library's warnings (util/warning.h) on Python's sys.stderr, where a notebook
// shows them (the command line writes them to the process's stderr, which a notebook does not).
// A sink queues each text from whatever thread warns; the module's calls write the queue out on
// the calling thread with the GIL held: each binding through the call guard FlushWarnings, a
// render also while it waits for its devices.
#pragma once

namespace spectrack {
namespace python {

// Sends the library's warnings to the queue (at import).
void install_warning_queue();
// Writes the queued warnings to sys.stderr as "warning: TEXT" lines; the GIL must be held. Never
// throws: a sys.stderr that cannot be written loses the text.
void flush_warnings();

// py::call_guard<FlushWarnings>(): the queue is written when the bound call returns or raises.
struct FlushWarnings {
  FlushWarnings() = default;
  FlushWarnings(const FlushWarnings&) = delete;
  FlushWarnings& operator=(const FlushWarnings&) = delete;
  ~FlushWarnings() { flush_warnings(); }
};

}  // namespace python
}  // namespace spectrack
