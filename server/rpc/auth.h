// Bearer tokens with roles: clients submit and download, workers lease and return tiles,
// administrators may do both; a metrics token reads the Prometheus endpoint and nothing else.
#pragma once

#include "cpvs/base/error.h"
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace cpvs::server {

/// A token must be at least this long and, drawn at random from the character classes it
/// uses, hold at least this many bits: 32 hex digits at the least.
constexpr size_t kMinTokenChars = 32;
constexpr double kMinTokenBits = 128;

/// Why a token cannot be trusted (a placeholder such as REPLACE_WITH_..., too short, too
/// few bits, too regular), or nothing when it may be used.
std::optional<std::string> weaknessOf(const std::string& token);

enum class Role { Client, Worker, Admin, Metrics };

const char* roleName(Role r);

/// Who a token is: its role, and the owner its jobs are recorded under.
struct TokenHolder {
  Role role;
  std::string owner;
};

class TokenTable {
 public:
  /// No tokens: every call is allowed (a farm on a trusted network, or tests).
  TokenTable() = default;
  /// Reads "ROLE TOKEN [OWNER]" lines (ROLE: client, worker, admin or metrics; '#' starts a
  /// comment). OWNER (1-64 of A-Z a-z 0-9 . _ -) names whose jobs a client token sees:
  /// tokens of one owner share their jobs and tracks; without it each token is its own
  /// owner (R28). Throws InputError naming the file and line for anything else.
  static TokenTable load(const std::string& path);

  bool enabled() const { return !roles_.empty(); }
  /// The role of a token, if it is known. The table holds SHA-256 digests only, and looks
  /// a token up by its digest: no plaintext stays in memory, and how long a lookup takes
  /// tells nothing about how much of a guess matches a token (R18).
  std::optional<TokenHolder> holderOf(const std::string& token) const;
  std::optional<Role> roleOf(const std::string& token) const;
  /// The owner a token's jobs are recorded under (its OWNER, or "token-" and 12 hex
  /// digits of its digest); nullopt for an unknown token.
  std::optional<std::string> ownerOf(const std::string& token) const;
  /// The digests held, in hex: for the test that no token is kept as sent.
  std::vector<std::string> digestsForTests() const;
  /// Whether `role` may call an RPC that needs `needed` (admin may call anything).
  static bool allows(Role role, Role needed) { return role == Role::Admin || role == needed; }
  /// Whether a token may read the metrics endpoint (metrics and admin tokens may).
  bool readsMetrics(const std::string& token) const {
    const auto r = roleOf(token);
    return r && (*r == Role::Metrics || *r == Role::Admin);
  }

 private:
  std::map<std::string, TokenHolder> roles_;  // by SHA-256 digest (32 raw bytes)
};

}  // namespace cpvs::server
