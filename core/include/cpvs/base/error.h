// The error policy of the core, in three tiers (as pbrt's check.h and error.h):
//   CPVS_CHECK(cond)   an invariant, always checked; a failure is a bug and aborts with its place.
//   CPVS_DCHECK(cond)  the same in debug builds only, for hot loops (compiled out under NDEBUG).
//   InputError         the caller's mistake (a bad file, option or argument), thrown with
//                      context and recovered from; FormatError is the subtype for bad bytes.
#pragma once

#include <stdexcept>
#include <string>

namespace cpvs {

/// Thrown for input the caller can fix: a bad file, a bad option, an invalid argument.
/// The message names what was wrong and where (file, index, field).
class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Thrown for bytes that are not a valid artifact, sub-DAG or scene: truncated, corrupted
/// or foreign. The message names the source and the field or byte offset.
class FormatError : public InputError {
 public:
  using InputError::InputError;
};

/// Thrown when long work is cancelled through a progress callback.
class Cancelled : public std::runtime_error {
 public:
  Cancelled() : std::runtime_error("cancelled") {}
};

namespace detail {
/// Prints "file:line: check failed: expr" to stderr and aborts.
[[noreturn]] void checkFailed(const char* expr, const char* file, int line);
}  // namespace detail

}  // namespace cpvs

#define CPVS_CHECK(cond) \
  ((cond) ? static_cast<void>(0) : ::cpvs::detail::checkFailed(#cond, __FILE__, __LINE__))

#ifdef NDEBUG
#define CPVS_DCHECK(cond) static_cast<void>(sizeof(static_cast<bool>(cond)))
#else
#define CPVS_DCHECK(cond) CPVS_CHECK(cond)
#endif
