#include "cpvs/metrics/checks.h"

#include <fcntl.h>
#include <openssl/pem.h>
#include <openssl/x509.h>
#include <openssl/x509v3.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <memory>

namespace cpvs::metrics {

namespace {

struct X509Free {
  void operator()(X509* x) const { X509_free(x); }
};

std::unique_ptr<X509, X509Free> readCertificate(const std::string& path) {
  FILE* f = std::fopen(path.c_str(), "r");
  if (!f) return nullptr;
  X509* x = PEM_read_X509(f, nullptr, nullptr, nullptr);
  std::fclose(f);
  return std::unique_ptr<X509, X509Free>(x);
}

std::string mib(uint64_t bytes) { return std::to_string(bytes >> 20) + " MiB"; }

}  // namespace

void Checks::check(bool passed, const std::string& what, bool warnOnly) {
  lines_.push_back((passed ? "ok:      " : warnOnly ? "warning: " : "FAIL:    ") + what);
  if (!passed && !warnOnly) failed_ = true;
}

void Checks::folderWritable(const std::string& dir) {
  const std::string probe = dir + "/.check." + std::to_string(::getpid());
  const int fd = ::open(probe.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
  bool written = fd >= 0 && ::write(fd, "ok", 2) == 2 && ::fsync(fd) == 0;
  const std::string why = std::strerror(errno);
  if (fd >= 0) ::close(fd);
  ::unlink(probe.c_str());
  check(written, dir + (written ? " takes a file" : " does not take a file: " + why));
}

void Checks::freeSpace(const std::string& dir, uint64_t minBytes) {
  struct statvfs s {};
  if (::statvfs(dir.c_str(), &s) != 0) {
    check(false, "cannot read the free space of " + dir + ": " + std::strerror(errno));
    return;
  }
  const uint64_t free = uint64_t(s.f_bavail) * uint64_t(s.f_frsize);
  check(free >= minBytes, dir + " has " + mib(free) + " free (at least " + mib(minBytes) + " wanted)");
}

void Checks::certificate(const std::string& pemPath, const char* role, int warnDays) {
  const auto x = readCertificate(pemPath);
  if (!x) {
    check(false, std::string("the ") + role + " certificate " + pemPath + " cannot be read as PEM");
    return;
  }
  time_t now = std::time(nullptr);
  if (X509_cmp_time(X509_get0_notBefore(x.get()), &now) > 0) {
    check(false, std::string("the ") + role + " certificate " + pemPath + " is not valid yet");
    return;
  }
  int days = 0, seconds = 0;
  ASN1_TIME_diff(&days, &seconds, nullptr, X509_get0_notAfter(x.get()));
  if (days < 0 || (days == 0 && seconds <= 0)) {
    check(false, std::string("the ") + role + " certificate " + pemPath + " has expired");
    return;
  }
  check(days >= warnDays,
        std::string("the ") + role + " certificate " + pemPath + " is valid for " + std::to_string(days) + " more days",
        true);
}

int Checks::finish() const {
  for (const std::string& line : lines_) std::printf("%s\n", line.c_str());
  std::fflush(stdout);
  return failed_ ? 1 : 0;
}

std::string certificateName(const std::string& pemPath) {
  const auto x = readCertificate(pemPath);
  if (!x) return {};
  auto* names = static_cast<GENERAL_NAMES*>(X509_get_ext_d2i(x.get(), NID_subject_alt_name, nullptr, nullptr));
  std::string out;
  for (int i = 0; names && i < sk_GENERAL_NAME_num(names) && out.empty(); ++i) {
    const GENERAL_NAME* n = sk_GENERAL_NAME_value(names, i);
    if (n->type == GEN_DNS)
      out.assign(reinterpret_cast<const char*>(ASN1_STRING_get0_data(n->d.dNSName)), size_t(ASN1_STRING_length(n->d.dNSName)));
  }
  GENERAL_NAMES_free(names);
  return out;
}

}  // namespace cpvs::metrics
