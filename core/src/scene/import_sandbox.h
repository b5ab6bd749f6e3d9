// The system-call filter of the import child: once in, the process reads files and writes
// to the pipes it was given, and nothing else: no network, no file made, changed or
// removed, no program run, no process made (threads still are), no other process touched.
#pragma once

#include <string>

namespace cpvs {

/// Installs the filter (seccomp, with no_new_privs) in this process and its threads from
/// now on. Returns why it could not, or nothing.
std::string enterImportSandbox();

}  // namespace cpvs
