// phase.h: the name of the step the process is in (scene loading, scene packing, kernel build,
// film allocation, ...), for the messages that say where a command was when it was stopped (the
// CLI's time limit). One slot per process: the steps of a command follow each other (several
// devices set it in turn during their set-up; the last one named is reported).
#pragma once
#include <atomic>

namespace spectrack {

// The slot; its value is always a string literal.
inline std::atomic<const char*>& phase_slot() {
  static std::atomic<const char*> phase{"start-up"};
  return phase;
}
inline void set_phase(const char* name) { phase_slot().store(name); }

}  // namespace spectrack
