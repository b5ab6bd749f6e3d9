// Crash points for the tests: with CPVS_FAILPOINT=NAME in its environment the coordinator
// kills itself with SIGKILL the first time it passes the point called NAME, as a power cut
// or the OOM killer would at that moment. Free when the variable is not set.
#pragma once

#include <signal.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>

namespace cpvs::server {

inline void failpoint(const char* name) {
  static const char* const armed = std::getenv("CPVS_FAILPOINT");
  if (armed != nullptr && std::strcmp(armed, name) == 0) ::kill(::getpid(), SIGKILL);
}

}  // namespace cpvs::server
