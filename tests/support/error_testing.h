// What a test expects of refused input: the InputError's message.
#pragma once

#include <string>

#include "cpvs/base/error.h"

namespace cpvs::testing {

/// The message of the InputError `fn` throws, "" when it throws none (other exceptions
/// pass through and fail the test).
template <class Fn>
std::string inputErrorOf(Fn&& fn) {
  try {
    fn();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

}  // namespace cpvs::testing
