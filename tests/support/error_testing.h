// What a test expects of refused input: the InputError's message.
#pragma once

#include <gtest/gtest.h>

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

/// Fails the test unless `fn` throws an InputError whose message holds `part`.
template <class Fn>
void expectInputError(Fn&& fn, const std::string& part) {
  const std::string message = inputErrorOf(fn);
  EXPECT_NE(message.find(part), std::string::npos) << "got '" << message << "', expected it to say '" << part << "'";
}

}  // namespace cpvs::testing
