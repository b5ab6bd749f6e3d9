// Who asks, as far as jobs and tracks go (R28): a client sees, follows, cancels and
// downloads what it submitted, and what was made on a farm without tokens; an
// administrator, and every caller of a farm without tokens, sees everything.
#pragma once

#include <string>

namespace cpvs::server {

struct Access {
  std::string owner;        // recorded on the jobs and tracks this caller creates
  bool everything = true;   // an administrator, or no tokens

  /// Everything, for the coordinator's own calls.
  static Access all() { return {}; }
  static Access of(const std::string& owner) { return {owner, false}; }

  bool sees(const std::string& recordOwner) const {
    return everything || recordOwner.empty() || recordOwner == owner;
  }
};

}  // namespace cpvs::server
