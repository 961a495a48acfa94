// fuzz_contract.h: how every harness reports a violated contract: one line on stderr naming the
// harness (its binary, e.g. fuzz_nvdb) and the broken promise, then abort(), which libFuzzer
// records as a crash and keeps the input that caused it.
#pragma once

#include <errno.h>  // program_invocation_short_name (glibc)

#include <cstdio>
#include <cstdlib>
#include <string>

[[noreturn]] inline void finding(const std::string& what) {
  std::fprintf(stderr, "%s: contract violated: %s\n", program_invocation_short_name, what.c_str());
  std::fflush(stderr);
  std::abort();
}

inline void check(bool ok, const char* what) {
  if (!ok) finding(what);
}
