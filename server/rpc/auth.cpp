#include "rpc/auth.h"

#include <fstream>
#include <sstream>

#include "cpvs/base/vec3.h"
#include "cpvs/base/hash.h"
#include "cpvs/base/error.h"

namespace cpvs::server {

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
    if (!t.roles_.emplace(token, r).second) throw InputError(where + ": the token is listed twice");
  }
  if (t.roles_.empty()) throw InputError(path + ": no tokens");
  return t;
}

std::optional<Role> TokenTable::roleOf(const std::string& token) const {
  auto it = roles_.find(token);
  if (it == roles_.end()) return std::nullopt;
  return it->second;
}

}  // namespace cpvs::server
