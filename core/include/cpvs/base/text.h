// Text that crosses a boundary where it must be valid UTF-8 (protobuf strings, JSON).
#pragma once

#include <cstddef>
#include <string>

namespace cpvs {

/// `text` as valid UTF-8 of at most `maxBytes` bytes: every invalid or truncated sequence
/// replaced by U+FFFD, and cut before the first character that would not fit whole.
std::string validUtf8Prefix(const std::string& text, size_t maxBytes);

/// `text` safe to put in a log line or on a terminal: valid UTF-8 of at most `maxBytes`,
/// every control character (newlines, ESC of terminal sequences, ...) written as \xNN.
std::string loggable(const std::string& text, size_t maxBytes = 200);

/// A JSON string literal of `s` (quotes, backslashes and control characters escaped).
std::string jsonString(const std::string& s);
/// A JSON number of `v` (9 significant digits), null when not finite.
std::string jsonNumber(double v);

}  // namespace cpvs
