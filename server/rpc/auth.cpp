#include "rpc/auth.h"

#include <openssl/evp.h>

#include <cctype>
#include <cmath>
#include <cstdio>
#include <set>
#include <fstream>
#include <stdexcept>
#include <sstream>

#include "cpvs/base/vec3.h"
#include "cpvs/base/hash.h"
#include "cpvs/base/error.h"

namespace cpvs::server {

namespace {

// SHA-256 of a token, 32 raw bytes.
std::string digestOf(const std::string& token) {
  unsigned char out[EVP_MAX_MD_SIZE];
  unsigned int size = 0;
  if (EVP_Digest(token.data(), token.size(), out, &size, EVP_sha256(), nullptr) != 1 || size != 32)
    throw std::runtime_error("SHA-256 is not available from OpenSSL");
  return std::string(reinterpret_cast<const char*>(out), size);
}

std::string hexOf(const std::string& bytes) {
  std::string hex;
  char b[3];
  for (unsigned char c : bytes) hex += (std::snprintf(b, sizeof b, "%02x", c), b);
  return hex;
}

}  // namespace

std::optional<std::string> weaknessOf(const std::string& token) {
  std::string lower;
  for (char c : token) lower += char(std::tolower(static_cast<unsigned char>(c)));
  for (const char* placeholder : {"replace", "changeme", "change_me", "change-me", "placeholder", "example", "password",
                                  "your_", "your-", "xxxx"})
    if (lower.find(placeholder) != std::string::npos)
      return std::string("it looks like a placeholder ('") + placeholder + "')";
  if (token.size() < kMinTokenChars)
    return "it has " + std::to_string(token.size()) + " characters, fewer than " + std::to_string(kMinTokenChars);
  // Bits a random token of this length over the character classes it uses would hold.
  bool digit = false, lowerCase = false, upperCase = false, other = false, hex = true;
  for (unsigned char c : token) {
    if (c < 0x21 || c > 0x7e) return std::string("it holds a character that is not printable ASCII");
    if (std::isdigit(c)) digit = true;
    else if (std::islower(c)) lowerCase = true;
    else if (std::isupper(c)) upperCase = true;
    else other = true;
    hex = hex && std::isxdigit(c);
  }
  const double alphabet = !lowerCase && !upperCase && !other ? 10
                          : hex && !(lowerCase && upperCase)  ? 16
                                                              : digit * 10 + lowerCase * 26 + upperCase * 26 + other * 32;
  if (double bits = double(token.size()) * std::log2(alphabet); bits < kMinTokenBits)
    return "it can hold about " + std::to_string(int(bits)) + " bits, fewer than " + std::to_string(int(kMinTokenBits));
  // Random tokens are irregular: few distinct characters, long runs or a short repeated
  // pattern mean a person made it up.
  if (std::set<char>(token.begin(), token.end()).size() < 10) return std::string("it uses fewer than 10 distinct characters");
  for (size_t period = 1; period <= token.size() / 2; ++period) {
    bool repeats = true;
    for (size_t i = period; i < token.size() && repeats; ++i) repeats = token[i] == token[i - period];
    if (repeats) return "it repeats a pattern of " + std::to_string(period) + " characters";
  }
  size_t run = 1;
  for (size_t i = 1; i < token.size(); ++i)
    if ((run = token[i] == token[i - 1] ? run + 1 : 1) > 8) return std::string("it repeats one character 9 times");
  return std::nullopt;
}

const char* roleName(Role r) {
  switch (r) {
    case Role::Client: return "client";
    case Role::Worker: return "worker";
    case Role::Admin: return "admin";
    case Role::Metrics: return "metrics";
  }
  return "?";
}

TokenTable TokenTable::load(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError("cannot read the tokens file " + path);
  TokenTable t;
  std::string line;
  int lineNo = 0;
  while (std::getline(in, line)) {
    ++lineNo;
    if (auto hash = line.find('#'); hash != std::string::npos) line.resize(hash);
    std::istringstream words(line);
    std::string role, token, owner, extra;
    if (!(words >> role)) continue;
    std::string where = path + " line " + std::to_string(lineNo);
    if (!(words >> token) || ((words >> owner) && (words >> extra))) throw InputError(where + ": expected ROLE TOKEN [OWNER]");
    bool ownerValid = owner.size() <= 64;
    for (char c : owner) ownerValid = ownerValid && (std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '_' || c == '-');
    if (!ownerValid) throw InputError(where + ": an owner is 1-64 of A-Z a-z 0-9 . _ -");
    if (auto weak = weaknessOf(token))
      throw InputError(where + ": the " + role + " token is too weak to trust: " + *weak +
                       " (bash deploy/make-secrets.sh makes random ones: 64 hex digits)");
    Role r;
    if (role == "client") r = Role::Client;
    else if (role == "worker") r = Role::Worker;
    else if (role == "admin") r = Role::Admin;
    else if (role == "metrics") r = Role::Metrics;
    else throw InputError(where + ": unknown role '" + role + "' (client, worker, admin or metrics)");
    const std::string digest = digestOf(token);
    if (owner.empty()) owner = "token-" + hexOf(digest.substr(0, 6));
    if (!t.roles_.emplace(digest, TokenHolder{r, owner}).second) throw InputError(where + ": the token is listed twice");
  }
  if (t.roles_.empty()) throw InputError(path + ": no tokens");
  return t;
}

std::optional<TokenHolder> TokenTable::holderOf(const std::string& token) const {
  auto it = roles_.find(digestOf(token));
  if (it == roles_.end()) return std::nullopt;
  return it->second;
}

std::optional<Role> TokenTable::roleOf(const std::string& token) const {
  const auto holder = holderOf(token);
  return holder ? std::optional<Role>(holder->role) : std::nullopt;
}

std::optional<std::string> TokenTable::ownerOf(const std::string& token) const {
  const auto holder = holderOf(token);
  return holder ? std::optional<std::string>(holder->owner) : std::nullopt;
}

std::vector<std::string> TokenTable::digestsForTests() const {
  std::vector<std::string> out;
  for (const auto& entry : roles_) out.push_back(hexOf(entry.first));
  return out;
}

}  // namespace cpvs::server
