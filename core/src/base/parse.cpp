#include "cpvs/base/parse.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <sstream>

#include "cpvs/base/error.h"
#include "cpvs/base/limits.h"

namespace cpvs {

std::vector<std::string> splitList(const std::string& text) {
  std::vector<std::string> out;
  if (text.empty()) return out;
  size_t begin = 0;
  while (true) {
    const size_t comma = text.find(',', begin);
    const std::string item = text.substr(begin, comma == std::string::npos ? std::string::npos : comma - begin);
    const auto b = item.find_first_not_of(" \t"), e = item.find_last_not_of(" \t");
    out.push_back(b == std::string::npos ? std::string() : item.substr(b, e - b + 1));
    if (comma == std::string::npos) return out;
    begin = comma + 1;
  }
}

std::vector<double> parseNumbers(const std::string& text, const std::string& what) {
  std::vector<double> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    size_t used = 0;
    double v;
    try {
      v = std::stod(item, &used);
    } catch (...) {
      throw InputError(what + ": '" + item + "' is not a number");
    }
    while (used < item.size() && std::isspace(static_cast<unsigned char>(item[used]))) ++used;
    if (used != item.size()) throw InputError(what + ": '" + item + "' is not a number");
    if (!std::isfinite(v)) throw InputError(what + ": '" + item + "' is not finite");
    out.push_back(v);
  }
  return out;
}

Vec3 parseVec3(const std::string& text, const std::string& what) {
  auto v = parseNumbers(text, what);
  if (v.size() != 3) throw InputError(what + ": expected X,Y,Z, got '" + text + "'");
  return {v[0], v[1], v[2]};
}

int parseResolution(const std::string& text) {
  std::string t;
  for (char c : text)
    if (!std::isspace(static_cast<unsigned char>(c))) t += c;
  if (t.empty()) throw InputError("resolution is empty");
  uint64_t mult = 1;
  char last = static_cast<char>(std::toupper(static_cast<unsigned char>(t.back())));
  if (last == 'K') {
    mult = 1024;
    t.pop_back();
  }
  if (t.empty() || t.size() > 9 || !std::all_of(t.begin(), t.end(), ::isdigit))
    throw InputError("resolution '" + text + "' is not a number like 4096 or 16K");
  uint64_t r = std::stoull(t) * mult;
  if (r == 0 || (r & (r - 1)) != 0)
    throw InputError("resolution '" + text + "' is not a power of two");
  int k = 0;
  while ((uint64_t(1) << k) < r) ++k;
  if (k < kMinLog2Resolution || k > kMaxLog2Resolution)
    throw InputError("resolution '" + text + "' is outside the supported range " +
                     std::to_string(1u << kMinLog2Resolution) + " .. " +
                     std::to_string(1u << kMaxLog2Resolution));
  return k;
}

std::vector<std::string> splitAt(const std::string& text, char separator) {
  std::vector<std::string> out(1);
  for (char c : text) {
    if (c == separator) out.emplace_back();
    else out.back() += c;
  }
  return out;
}

}  // namespace cpvs
