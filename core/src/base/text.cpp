#include "cpvs/base/text.h"

#include <cmath>
#include <cstdint>
#include <cstdio>

namespace cpvs {

namespace {

constexpr char kReplacement[] = "\xEF\xBF\xBD";  // U+FFFD

// The length of the valid UTF-8 sequence starting at text[i], or 0 when there is none
// (RFC 3629: no overlong forms, no surrogates, nothing above U+10FFFF).
size_t sequenceLength(const std::string& text, size_t i) {
  const auto byte = [&](size_t k) { return k < text.size() ? uint8_t(text[k]) : uint8_t(0); };
  const auto cont = [&](size_t k) { return (byte(k) & 0xC0) == 0x80; };
  const uint8_t b = byte(i);
  if (b < 0x80) return 1;
  if (b >= 0xC2 && b <= 0xDF) return cont(i + 1) ? 2 : 0;
  if (b >= 0xE0 && b <= 0xEF) {
    const uint8_t b1 = byte(i + 1);
    const bool ok = (b == 0xE0 ? b1 >= 0xA0 : true) && (b == 0xED ? b1 < 0xA0 : true);
    return ok && cont(i + 1) && cont(i + 2) ? 3 : 0;
  }
  if (b >= 0xF0 && b <= 0xF4) {
    const uint8_t b1 = byte(i + 1);
    const bool ok = (b == 0xF0 ? b1 >= 0x90 : true) && (b == 0xF4 ? b1 < 0x90 : true);
    return ok && cont(i + 1) && cont(i + 2) && cont(i + 3) ? 4 : 0;
  }
  return 0;
}

}  // namespace

std::string validUtf8Prefix(const std::string& text, size_t maxBytes) {
  std::string out;
  for (size_t i = 0; i < text.size();) {
    const size_t n = sequenceLength(text, i);
    const size_t add = n ? n : sizeof kReplacement - 1;
    if (out.size() + add > maxBytes) break;
    if (n) {
      out.append(text, i, n);
      i += n;
    } else {
      // One replacement for the maximal invalid run: a bad lead byte and the
      // continuation bytes that follow it.
      out += kReplacement;
      ++i;
      for (int k = 0; k < 3 && i < text.size() && (uint8_t(text[i]) & 0xC0) == 0x80; ++k) ++i;
    }
  }
  return out;
}

std::string loggable(const std::string& text, size_t maxBytes) {
  std::string out;
  for (char c : validUtf8Prefix(text, maxBytes)) {
    const auto u = static_cast<unsigned char>(c);
    if (u < 0x20 || u == 0x7F) {
      char esc[5];
      std::snprintf(esc, sizeof esc, "\\x%02X", u);
      out += esc;
    } else {
      out += c;
    }
  }
  return out;
}

std::string jsonString(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    switch (c) {
      case '"': out += "\\\""; break;
      case '\\': out += "\\\\"; break;
      case '\n': out += "\\n"; break;
      case '\t': out += "\\t"; break;
      default:
        if (static_cast<unsigned char>(c) < 0x20) {
          char buf[8];
          std::snprintf(buf, sizeof buf, "\\u%04x", c);
          out += buf;
        } else {
          out += c;
        }
    }
  }
  return out + "\"";
}

std::string jsonNumber(double v) {
  if (!std::isfinite(v)) return "null";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.9g", v);
  return buf;
}

}  // namespace cpvs
