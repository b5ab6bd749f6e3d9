#include "import_sandbox.h"

#include <fcntl.h>
#include <sched.h>
#include <seccomp.h>

#include <cerrno>
#include <cstring>

namespace cpvs {

std::string enterImportSandbox() {
  // A deny list over an allowed default: what an importer needs (reading, mapping,
  // allocating, threads, time) differs between libc and assimp versions, what it must
  // never do does not.
  scmp_filter_ctx ctx = seccomp_init(SCMP_ACT_ALLOW);
  if (!ctx) return "seccomp_init failed";
  const uint32_t denied = SCMP_ACT_ERRNO(EACCES);
  int rc = 0;
  const auto deny = [&](int call) {
    if (rc == 0 && call >= 0) rc = seccomp_rule_add(ctx, denied, call, 0);
  };
  // The network: without a socket there is none.
  for (int call : {SCMP_SYS(socket), SCMP_SYS(socketpair), SCMP_SYS(connect), SCMP_SYS(bind), SCMP_SYS(listen),
                   SCMP_SYS(accept), SCMP_SYS(accept4), SCMP_SYS(sendto), SCMP_SYS(sendmsg), SCMP_SYS(sendmmsg)})
    deny(call);
  // Files made, changed or removed (RLIMIT_FSIZE already stops writing bytes).
  for (int call : {SCMP_SYS(unlink), SCMP_SYS(unlinkat), SCMP_SYS(rename), SCMP_SYS(renameat), SCMP_SYS(renameat2),
                   SCMP_SYS(mkdir), SCMP_SYS(mkdirat), SCMP_SYS(rmdir), SCMP_SYS(link), SCMP_SYS(linkat),
                   SCMP_SYS(symlink), SCMP_SYS(symlinkat), SCMP_SYS(chmod), SCMP_SYS(fchmod), SCMP_SYS(fchmodat),
                   SCMP_SYS(chown), SCMP_SYS(fchown), SCMP_SYS(fchownat), SCMP_SYS(lchown), SCMP_SYS(truncate),
                   SCMP_SYS(mknod), SCMP_SYS(mknodat), SCMP_SYS(utime), SCMP_SYS(utimes), SCMP_SYS(utimensat),
                   SCMP_SYS(creat), SCMP_SYS(memfd_create), SCMP_SYS(mount), SCMP_SYS(umount2)})
    deny(call);
  // Opening a file for anything but reading.
  for (scmp_datum_t bit : {scmp_datum_t(O_WRONLY), scmp_datum_t(O_RDWR), scmp_datum_t(O_CREAT), scmp_datum_t(O_TRUNC),
                           scmp_datum_t(O_APPEND)}) {
    if (rc == 0) rc = seccomp_rule_add(ctx, denied, SCMP_SYS(open), 1, SCMP_A1(SCMP_CMP_MASKED_EQ, bit, bit));
    if (rc == 0) rc = seccomp_rule_add(ctx, denied, SCMP_SYS(openat), 1, SCMP_A2(SCMP_CMP_MASKED_EQ, bit, bit));
  }
  deny(SCMP_SYS(openat2));  // its flags are behind a pointer: not for an importer
  // Programs and processes: threads only (clone with CLONE_THREAD; clone3's flags are
  // behind a pointer, and glibc falls back to clone when it is refused).
  for (int call : {SCMP_SYS(execve), SCMP_SYS(execveat), SCMP_SYS(fork), SCMP_SYS(vfork), SCMP_SYS(ptrace),
                   SCMP_SYS(process_vm_writev), SCMP_SYS(process_vm_readv), SCMP_SYS(kill), SCMP_SYS(tkill)})
    deny(call);
  if (rc == 0) rc = seccomp_rule_add(ctx, denied, SCMP_SYS(clone), 1, SCMP_A0(SCMP_CMP_MASKED_EQ, CLONE_THREAD, 0));
  if (rc == 0) rc = seccomp_rule_add(ctx, SCMP_ACT_ERRNO(ENOSYS), SCMP_SYS(clone3), 0);
  if (rc == 0) rc = seccomp_load(ctx);
  seccomp_release(ctx);
  return rc == 0 ? std::string() : std::string("seccomp: ") + std::strerror(-rc);
}

}  // namespace cpvs
