// LD_PRELOAD shim for the disk-full tests: while the file named by CPVS_ENOSPC_FLAG exists,
// every write to a file whose path starts with the text that file holds (a folder) fails
// with ENOSPC, as on a full disk; other writes (sockets, logs, pipes) go through. Remove
// the flag and the disk has space again.
#define _GNU_SOURCE
#include <dlfcn.h>
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/types.h>
#include <sys/uio.h>
#include <unistd.h>

static int full(int fd) {
  const char* flag = getenv("CPVS_ENOSPC_FLAG");
  if (flag == NULL) return 0;
  const int f = open(flag, O_RDONLY | O_CLOEXEC);
  if (f < 0) return 0;
  char prefix[4096];
  const ssize_t got = read(f, prefix, sizeof prefix - 1);
  close(f);
  if (got <= 0) return 0;
  prefix[got] = 0;
  prefix[strcspn(prefix, "\n")] = 0;
  char link[64], path[4096];
  snprintf(link, sizeof link, "/proc/self/fd/%d", fd);
  const ssize_t n = readlink(link, path, sizeof path - 1);
  if (n <= 0) return 0;
  path[n] = 0;
  return prefix[0] != 0 && strncmp(path, prefix, strlen(prefix)) == 0;
}

typedef ssize_t (*write_fn)(int, const void*, size_t);
typedef ssize_t (*pwrite_fn)(int, const void*, size_t, off_t);
typedef ssize_t (*pwrite64_fn)(int, const void*, size_t, off64_t);
typedef ssize_t (*writev_fn)(int, const struct iovec*, int);

#define REAL(name, type) \
  static type real = NULL; \
  if (real == NULL) real = (type)dlsym(RTLD_NEXT, name)

ssize_t write(int fd, const void* buf, size_t count) {
  REAL("write", write_fn);
  if (full(fd)) {
    errno = ENOSPC;
    return -1;
  }
  return real(fd, buf, count);
}

ssize_t pwrite(int fd, const void* buf, size_t count, off_t offset) {
  REAL("pwrite", pwrite_fn);
  if (full(fd)) {
    errno = ENOSPC;
    return -1;
  }
  return real(fd, buf, count, offset);
}

ssize_t pwrite64(int fd, const void* buf, size_t count, off64_t offset) {
  REAL("pwrite64", pwrite64_fn);
  if (full(fd)) {
    errno = ENOSPC;
    return -1;
  }
  return real(fd, buf, count, offset);
}

ssize_t writev(int fd, const struct iovec* iov, int iovcnt) {
  REAL("writev", writev_fn);
  if (full(fd)) {
    errno = ENOSPC;
    return -1;
  }
  return real(fd, iov, iovcnt);
}
