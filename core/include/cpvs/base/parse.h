// Parsing of user-given text: numbers, vectors, lists, resolutions. Every function
// throws InputError naming `what` (a flag or field) and the text it could not read.
#pragma once

#include <string>
#include <vector>

#include "cpvs/base/vec3.h"

namespace cpvs {

/// Splits on commas, trimming spaces around each item. Empty items are kept (",," is a
/// typo the caller should report); an empty text gives no items.
std::vector<std::string> splitList(const std::string& text);

/// "A:B[:C...]" split at every `separator`, nothing trimmed: "a::b" gives an empty field.
std::vector<std::string> splitAt(const std::string& text, char separator);

/// Comma-separated finite numbers ("1, 2.5,-3").
std::vector<double> parseNumbers(const std::string& text, const std::string& what);

/// "X,Y,Z" into a finite vector.
Vec3 parseVec3(const std::string& text, const std::string& what);

/// "4096", "4K", "16k", "256K" into log2 of a power of two in [kMinLog2Resolution,
/// kMaxLog2Resolution] (base/limits.h).
int parseResolution(const std::string& text);

}  // namespace cpvs
