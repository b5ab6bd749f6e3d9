#include "rpc/auth.h"

#include <openssl/evp.h>

#include <cstdio>
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

}  // namespace

const char* roleName(Role r) {
  switch (r) {
    case Role::Client: return "client";
    case Role::Worker: return "worker";
    case Role::Admin: return "admin";
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
    std::string role, token, extra;
    if (!(words >> role)) continue;
    std::string where = path + " line " + std::to_string(lineNo);
    if (!(words >> token) || (words >> extra)) throw InputError(where + ": expected ROLE TOKEN");
    if (token.size() < 16) throw InputError(where + ": tokens must be at least 16 characters");
    Role r;
    if (role == "client") r = Role::Client;
    else if (role == "worker") r = Role::Worker;
    else if (role == "admin") r = Role::Admin;
    else throw InputError(where + ": unknown role '" + role + "' (client, worker or admin)");
    if (!t.roles_.emplace(digestOf(token), r).second) throw InputError(where + ": the token is listed twice");
  }
  if (t.roles_.empty()) throw InputError(path + ": no tokens");
  return t;
}

std::optional<Role> TokenTable::roleOf(const std::string& token) const {
  auto it = roles_.find(digestOf(token));
  if (it == roles_.end()) return std::nullopt;
  return it->second;
}

std::vector<std::string> TokenTable::digestsForTests() const {
  std::vector<std::string> out;
  for (const auto& [digest, role] : roles_) {
    std::string hex;
    char b[3];
    for (unsigned char c : digest) hex += (std::snprintf(b, sizeof b, "%02x", c), b);
    out.push_back(hex);
  }
  return out;
}

}  // namespace cpvs::server
